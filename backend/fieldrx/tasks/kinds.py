"""The task-kind registry: what kinds of background work there are, one class each.

A task kind is a ``TaskKind`` subclass in the module of its work, registered with
``@TASK_KINDS.register``: its name (the ``tasks.kind`` value), the queue its jobs go to,
where its result is seen (``result_url``) and its ``run``. ``tasks.work`` imports every
kind's module, so importing it (the worker, the API's task routes, ``fieldrx migrate``)
fills the registry. The list of kinds is read from here by the worker's ``--queues``
choices, the dispatch of ``tasks.work.execute`` and the database: ``tasks.kind`` is a
foreign key to ``task_kinds``, whose rows ``sync_task_kinds`` writes from this registry
(``fieldrx migrate``), so a new kind needs no migration.

This module imports only the registry: the API and the store read the kinds without the
work's modules.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from sqlalchemy import Engine, text

from fieldrx.registry import Registry

StopFn = Callable[[], bool]
API = "/api/v1"


@dataclass
class Claimed:
    """A task a worker has started: what the work needs from its row."""

    id: int
    kind: str
    params: dict[str, Any]
    organisation_id: int
    created_by: int | None
    attempts: int


class TaskKind:
    """One kind of task. ``result_key``/``result_route``: the result's id and the route that
    shows it (``("plan_id", "/plans/{}")``). A batch kind (``batch``) only groups the tasks
    of another kind: it has no queue job and nothing to run. ``stores_file``: its result
    is a file in ``task_files`` (``GET /tasks/{id}/download``)."""

    name: str = ""
    result_key: str = ""
    result_route: str = ""
    batch: bool = False
    stores_file: bool = False

    @property
    def queue(self) -> str:
        """The procrastinate queue of its jobs (``fieldrx worker --queues``)."""
        return "" if self.batch else self.name

    def result_url(self, result: dict[str, Any] | None) -> str | None:
        if not self.result_route or not result or result.get(self.result_key) is None:
            return None
        return API + self.result_route.format(int(result[self.result_key]))

    def run(self, claimed: Claimed, should_stop: StopFn) -> dict[str, Any]:
        raise NotImplementedError(f"task kind {self.name!r} runs nothing")


TASK_KINDS: Registry[TaskKind] = Registry("task kind")


def queues() -> tuple[str, ...]:
    """The queues of the registered kinds, in registration order."""
    return tuple(k.queue for k in TASK_KINDS if k.queue)


def stores_file(kind: str) -> bool:
    return kind in TASK_KINDS and TASK_KINDS.get(kind).stores_file


def result_url(kind: str, result: dict[str, Any] | None) -> str | None:
    return TASK_KINDS.get(kind).result_url(result) if kind in TASK_KINDS else None


def sync_task_kinds(engine: Engine) -> list[str]:
    """Insert the registered kinds missing from ``task_kinds`` (run by ``fieldrx migrate``
    after the migrations); returns the names added. Kinds no longer registered are kept:
    old tasks' rows still name them."""
    with engine.begin() as conn:
        have = set(conn.execute(text("SELECT name FROM task_kinds")).scalars())
        missing = [k.name for k in TASK_KINDS if k.name not in have]
        if missing:  # VALUES, not INSERT ... SELECT: a plain insert on a Citus reference table
            conn.execute(
                text("INSERT INTO task_kinds (name) VALUES (:n) ON CONFLICT (name) DO NOTHING"),
                [{"n": n} for n in missing],
            )
    return missing
