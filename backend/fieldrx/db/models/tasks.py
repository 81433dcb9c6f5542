"""Background tasks: the row the API and the UI see of a queued job, and the file a
task produced.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from sqlalchemy import (
    BigInteger,
    Boolean,
    CheckConstraint,
    DateTime,
    Double,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    String,
    Text,
    text,
)
from sqlalchemy.dialects.postgresql import JSONB
from sqlalchemy.orm import Mapped, mapped_column

from fieldrx.db.models.base import Base, now_column

TASK_STATES = ("queued", "running", "succeeded", "failed", "cancelled")


class TaskKindRow(Base):
    """A kind of task (``tasks.kind`` refers to it): the rows are written from the
    task-kind registry (``tasks.kinds.sync_task_kinds``, run by ``fieldrx migrate``), so
    the database admits exactly the kinds the code registers without a migration per kind."""

    __tablename__ = "task_kinds"
    name: Mapped[str] = mapped_column(String(32), primary_key=True)


class Task(Base):
    """Background work of an organisation: what the API and the UI see of a job on
    the PostgreSQL queue (procrastinate's ``procrastinate_jobs`` row ``job_id``).

    procrastinate knows how to run a job once and recover it from a dead worker; this row
    holds what FieldRx promises on top: organisation scoping, who asked, progress (0..1 and a
    message), the result (``{"plan_id": 7}``), the error a user can act on, and the
    cancellation request. A batch is a ``plan_batch`` row without a job whose children
    (``parent_id``) are the per-field tasks. The row is written in the same transaction as
    the work's result, which is what makes a retried job finish exactly once.
    """

    __tablename__ = "tasks"
    __table_args__ = (
        CheckConstraint(
            "status IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')",
            name="ck_tasks_status",
        ),
        CheckConstraint("progress >= 0 AND progress <= 1", name="ck_tasks_progress"),
        Index("ix_tasks_org_created", "organisation_id", "created_at"),
        Index("ix_tasks_parent", "parent_id"),
    )
    id: Mapped[int] = mapped_column(BigInteger, primary_key=True)
    organisation_id: Mapped[int] = mapped_column(ForeignKey("organisations.id", ondelete="CASCADE"))
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    parent_id: Mapped[int | None] = mapped_column(
        BigInteger, ForeignKey("tasks.id", ondelete="CASCADE")
    )
    kind: Mapped[str] = mapped_column(String(32), ForeignKey("task_kinds.name"))
    status: Mapped[str] = mapped_column(String(16), server_default="queued")
    progress: Mapped[float] = mapped_column(Double, server_default=text("0"))
    message: Mapped[str] = mapped_column(Text, server_default="")
    params: Mapped[dict[str, Any]] = mapped_column(JSONB, server_default=text("'{}'"))
    result: Mapped[dict[str, Any] | None] = mapped_column(JSONB)
    error: Mapped[str | None] = mapped_column(Text)
    cancel_requested: Mapped[bool] = mapped_column(Boolean, server_default=text("false"))
    job_id: Mapped[int | None] = mapped_column(BigInteger)
    attempts: Mapped[int] = mapped_column(Integer, server_default=text("0"))
    worker: Mapped[str] = mapped_column(String(200), server_default="")
    created_at: Mapped[dt.datetime] = now_column()
    updated_at: Mapped[dt.datetime] = now_column()
    started_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))
    finished_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))


class TaskFile(Base):
    """The file a task produced (revision 0015): an export to download, or a job report's
    per-cell snapshot that API processes read instead of recomputing it. Written in the
    transaction that marks the task succeeded (one file per task however often it runs);
    deleted by workers after ``FIELDRX_TASK_RESULT_RETENTION_S`` (``tasks.files``)."""

    __tablename__ = "task_files"
    __table_args__ = (Index("ix_task_files_created", "created_at"),)
    task_id: Mapped[int] = mapped_column(
        BigInteger, ForeignKey("tasks.id", ondelete="CASCADE"), primary_key=True
    )
    organisation_id: Mapped[int] = mapped_column(ForeignKey("organisations.id", ondelete="CASCADE"))
    filename: Mapped[str] = mapped_column(String(300))
    media_type: Mapped[str] = mapped_column(String(100))
    size: Mapped[int] = mapped_column(BigInteger)
    data: Mapped[bytes] = mapped_column(LargeBinary)
    created_at: Mapped[dt.datetime] = now_column()
