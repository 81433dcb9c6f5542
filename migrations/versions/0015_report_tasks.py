"""Exports and job reports as background tasks, and the files they produce.

Why: a large as-applied or prescription export, or the report of a long job, took
seconds to tens of seconds inside the HTTP request with no progress. They now run as
tasks (kinds ``export`` and ``report``) on the procrastinate queue. A task's file (the
export, or a report's per-cell snapshot that every API process can read instead of
recomputing it) is stored in ``task_files`` in the same transaction that marks the
task succeeded, so a retried task stores one file; workers delete files past their
retention (``FIELDRX_TASK_RESULT_RETENTION_S``). The bytes live in PostgreSQL so that
API processes and workers on different hosts see the same file with no shared disk;
``STORAGE EXTERNAL`` (no TOAST compression: zips are compressed already) lets the
download read it in slices (``substring``) without de-toasting the whole value.

Revision ID: 0015_report_tasks
Revises: 0014_machine_keys
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0015_report_tasks"
down_revision: str | Sequence[str] | None = "0014_machine_keys"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

OLD_KINDS = "kind IN ('plan', 'prescription', 'imagery', 'plan_batch')"
NEW_KINDS = "kind IN ('plan', 'prescription', 'imagery', 'plan_batch', 'export', 'report')"


def upgrade() -> None:
    op.drop_constraint("ck_tasks_kind", "tasks", type_="check")
    op.create_check_constraint("ck_tasks_kind", "tasks", NEW_KINDS)
    op.create_table(
        "task_files",
        sa.Column("task_id", sa.BigInteger(), nullable=False),
        sa.Column("organisation_id", sa.Integer(), nullable=False),
        sa.Column("filename", sa.String(length=300), nullable=False),
        sa.Column("media_type", sa.String(length=100), nullable=False),
        sa.Column("size", sa.BigInteger(), nullable=False),
        sa.Column("data", sa.LargeBinary(), nullable=False),
        sa.Column(
            "created_at",
            sa.DateTime(timezone=True),
            server_default=sa.text("now()"),
            nullable=False,
        ),
        sa.ForeignKeyConstraint(["task_id"], ["tasks.id"], ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["organisation_id"], ["organisations.id"], ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("task_id"),
    )
    op.execute("ALTER TABLE task_files ALTER COLUMN data SET STORAGE EXTERNAL")
    op.create_index("ix_task_files_created", "task_files", ["created_at"])


def downgrade() -> None:
    op.drop_index("ix_task_files_created", table_name="task_files")
    op.drop_table("task_files")
    op.execute("DELETE FROM tasks WHERE kind IN ('export', 'report')")
    op.drop_constraint("ck_tasks_kind", "tasks", type_="check")
    op.create_check_constraint("ck_tasks_kind", "tasks", OLD_KINDS)
