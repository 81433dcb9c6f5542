"""One registry per concept (export format, import format, task kind): the single list.

A concept's entries are classes that register themselves with ``@REGISTRY.register``
in their own module; the registry keeps one instance of each, in registration order
(which is also the order shown to users and, for import formats, the detection order).
Everything that used to repeat the names (the API's accepted values, the OpenAPI
document, the CLI's choices, the UI's menus, a database check) reads them from here,
so adding an entry touches its own module and nothing else.

Standard library only: every layer may import it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Generic, Protocol, TypeVar


class Named(Protocol):
    @property
    def name(self) -> str: ...


T = TypeVar("T", bound=Named)
C = TypeVar("C")


class Registry(Generic[T]):
    """Named entries of one concept, in registration order."""

    def __init__(self, what: str) -> None:
        self.what = what
        self._items: dict[str, T] = {}

    def add(self, item: T) -> T:
        if item.name in self._items:
            raise ValueError(f"{self.what} {item.name!r} is registered twice")
        self._items[item.name] = item
        return item

    def register(self, cls: type[C]) -> type[C]:
        """Class decorator: register one instance of ``cls`` (a subclass of the entry type)."""
        self.add(cls())  # type: ignore[arg-type]
        return cls

    def get(self, name: str) -> T:
        """The entry named ``name``; ``LookupError`` naming the known ones otherwise."""
        try:
            return self._items[name]
        except KeyError:
            raise LookupError(
                f"unknown {self.what} {name!r} (expected one of {list(self._items)})"
            ) from None

    def names(self, where: Callable[[T], bool] | None = None) -> tuple[str, ...]:
        return tuple(n for n, item in self._items.items() if where is None or where(item))

    def __contains__(self, name: object) -> bool:
        return name in self._items

    def __iter__(self) -> Iterator[T]:
        return iter(list(self._items.values()))

    def __len__(self) -> int:
        return len(self._items)
