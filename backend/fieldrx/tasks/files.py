"""Files that tasks produce: stored with the task's success, read in slices, purged.

An export task's file (CSV, zipped Shapefile, TASKDATA.zip, GeoJSON) and a report
task's per-cell snapshot live in ``task_files`` (revision 0015), one row per task,
written in the work's own transaction just before ``store.complete`` (so a task that
runs twice stores one file: ``fieldrx.tasks``, exactly once). PostgreSQL rather than a
directory: API processes and workers may run on different hosts with no shared disk.
The column is ``STORAGE EXTERNAL`` (uncompressed), so ``substring`` reads a slice
without de-toasting the whole value and a download streams in ``CHUNK`` pieces.

Files are deleted ``FIELDRX_TASK_RESULT_RETENTION_S`` after they were written by every
task worker (``purge_expired``, from ``tasks.worker``); the task row stays and its
download answers 410 then (run the export again).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterator
from dataclasses import dataclass

from sqlalchemy import Engine, delete, select, text
from sqlalchemy.orm import Session

from fieldrx.db.models import TaskFile

CHUNK = 1024 * 1024


@dataclass(frozen=True)
class FileInfo:
    """What a download needs before the bytes: name, media type, size."""

    task_id: int
    filename: str
    media_type: str
    size: int
    created_at: dt.datetime


def put(
    session: Session, task_id: int, organisation_id: int, data: bytes, media_type: str, name: str
) -> FileInfo:
    """Store the task's file in the session's transaction (flush only; the work's
    transaction completes the task and commits)."""
    row = TaskFile(
        task_id=task_id,
        organisation_id=organisation_id,
        filename=name[:300],
        media_type=media_type,
        size=len(data),
        data=data,
    )
    session.add(row)
    session.flush()
    return FileInfo(task_id, row.filename, media_type, len(data), dt.datetime.now(dt.UTC))


def info(session: Session, task_id: int) -> FileInfo | None:
    row = session.execute(
        select(TaskFile.filename, TaskFile.media_type, TaskFile.size, TaskFile.created_at).where(
            TaskFile.task_id == task_id
        )
    ).first()
    return None if row is None else FileInfo(task_id, row[0], row[1], int(row[2]), row[3])


def read(session: Session, task_id: int) -> bytes | None:
    """The whole file (report snapshots: small enough to hold)."""
    return session.scalar(select(TaskFile.data).where(TaskFile.task_id == task_id))


def iter_chunks(engine: Engine, task_id: int, size: int, chunk: int = CHUNK) -> Iterator[bytes]:
    """The file in ``chunk``-byte slices, each read on its own short connection (a download
    can take minutes on a slow link: no transaction stays open meanwhile). A file purged
    mid-download ends the stream early (the client sees a short body)."""
    offset = 0
    while offset < size:
        with engine.connect() as conn:
            part = conn.execute(
                text("SELECT substring(data FROM :o FOR :n) FROM task_files WHERE task_id = :id"),
                {"o": offset + 1, "n": chunk, "id": task_id},
            ).scalar()
        if not part:
            return
        yield bytes(part)
        offset += len(part)


def purge_expired(engine: Engine, retention_s: float) -> int:
    """Delete files written more than ``retention_s`` seconds ago; returns how many."""
    cutoff = dt.datetime.now(dt.UTC) - dt.timedelta(seconds=retention_s)
    with engine.begin() as conn:
        res = conn.execute(delete(TaskFile).where(TaskFile.created_at < cutoff))
    return int(res.rowcount or 0)
