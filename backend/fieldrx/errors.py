"""Domain errors shared by the services and the API layer.

Lower layers raise these; ``fieldrx.app`` maps each class to one HTTP status
(lower layers never import the API layer). Each message says what was refused
and what to change.
"""

from __future__ import annotations

from typing import Any


class DomainError(Exception):
    """Base class: ``status`` is the HTTP status the API answers, ``extra`` goes into the body."""

    status = 400

    def __init__(self, message: str, **extra: Any) -> None:
        super().__init__(message)
        self.message = message
        self.extra = extra

    def body(self) -> dict[str, Any]:
        return {"detail": self.message, **self.extra}


class Invalid(DomainError):
    """The request is well formed but its values cannot be used (a state that does not
    exist, a setting out of range); ``where`` names the field."""

    status = 422


class TooExpensive(DomainError):
    """A request's cost bound (rows, cells, bytes, time) is exceeded: refused before or while
    working, nothing stored."""

    status = 422


class TooLarge(DomainError):
    """A request body or upload is larger than allowed."""

    status = 413


class Conflict(DomainError):
    """The request conflicts with stored state (evidence that must not be erased, a concurrent
    change)."""

    status = 409


class Busy(DomainError):
    """The server is at its limit of concurrent heavy work or the database is unreachable;
    retry later."""

    status = 503


class Cancelled(DomainError):
    """The user cancelled the work (a background task); nothing of it was stored."""

    status = 409


class TooMany(DomainError):
    """A quota is used up for now (an organisation's open tasks): retry after
    ``retry_after_s`` seconds (the ``Retry-After`` header)."""

    status = 429

    def __init__(self, message: str, retry_after_s: int = 30, **extra: Any) -> None:
        super().__init__(message, **extra)
        self.retry_after_s = retry_after_s
