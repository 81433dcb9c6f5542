"""What a task's work runs with: its progress reporter, its input errors, the one
transaction that stores its result and completes it (exactly once: ``fieldrx.tasks``), and
the place of a queued upload.

Shared by the kinds' modules (``work``, ``exports``, ``imports``) so that none of them
imports another to get these: ``work`` dispatches to the kinds, the kinds import only
this module and ``store``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import psycopg
from sqlalchemy import text
from sqlalchemy.orm import Session

from fieldrx.db.session import limit_session, make_engine, raw_dsn
from fieldrx.errors import Cancelled, DomainError
from fieldrx.tasks import store

StopFn = Callable[[], bool]



class TaskInputError(ValueError):
    """What a queued task needs is gone (its field, plan or upload was deleted meanwhile)."""


class Progress:
    """``progress(share, message)`` for the task: written at most every ``min_interval_s``
    (and always at the end) on its own autocommit connection; raises ``Cancelled`` when the
    user asked to cancel."""

    def __init__(self, dsn: str, task_id: int, min_interval_s: float = 0.3) -> None:
        self.dsn = dsn
        self.task_id = task_id
        self.min_interval_s = min_interval_s
        self._conn: psycopg.Connection[Any] | None = None
        self._last = 0.0

    def __call__(self, share: float, message: str) -> None:
        now = time.monotonic()
        if share < 1.0 and now - self._last < self.min_interval_s:
            return
        self._last = now
        if self._conn is None:
            self._conn = psycopg.connect(self.dsn, autocommit=True)
        row = self._conn.execute(
            "UPDATE tasks SET progress = %s, message = %s, updated_at = now() "
            "WHERE id = %s AND status = 'running' RETURNING cancel_requested",
            (min(max(float(share), 0.0), 1.0), message[:500], self.task_id),
        ).fetchone()
        if row is not None and row[0]:
            raise Cancelled("the task was cancelled; nothing was stored")

    def close(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None


def is_user_error(exc: BaseException) -> bool:
    """Errors whose message tells the user what to change (FieldRx's domain errors, all
    ValueError subclasses defined in fieldrx, or DomainError), not internal failures."""
    if isinstance(exc, DomainError):
        return True
    return isinstance(exc, ValueError) and type(exc).__module__.startswith("fieldrx")


def _task_params(session: Session, task_id: int) -> tuple[dict[str, Any], int, int | None]:
    row = session.execute(
        text("SELECT params, organisation_id, created_by FROM tasks WHERE id = :id"),
        {"id": task_id},
    ).one()
    return dict(row[0]), int(row[1]), row[2]


def in_transaction(
    database_url: str,
    task_id: int,
    time_limit_s: float,
    work: Callable[[Session, dict[str, Any], int, int | None, Progress], tuple[dict, str]],
) -> dict[str, Any]:
    """Run ``work`` in one transaction that first takes the task's guard and ends by
    completing the task; the stored result of an earlier run is returned untouched."""
    from fieldrx.services.bounded import ensure_caller_alive

    engine = make_engine(database_url)
    progress = Progress(raw_dsn(database_url), task_id)
    try:
        with Session(engine) as session:
            limit_session(session, time_limit_s)
            done = store.guard(session, task_id)
            if done is not None:
                return done
            params, org, user = _task_params(session, task_id)
            result, message = work(session, params, org, user, progress)
            if not store.complete(session, task_id, result, message):
                session.rollback()  # another run completed it: its result stands
                return store.guard(session, task_id) or {}
            ensure_caller_alive("the task")  # its worker died: the retry stores it
            session.commit()
            return result
    finally:
        progress.close()
        engine.dispose()


def incoming_upload(name: str) -> Path:
    """The received upload a queued imagery task converts (``storage`` keeps it)."""
    from fieldrx.imagery import storage

    base = (storage.root() / ".incoming").resolve()
    path = (base / name).resolve()
    if path.parent != base:
        raise ValueError(f"incoming upload {name!r} leaves the upload folder")
    return path
