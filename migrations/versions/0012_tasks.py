"""Background tasks: procrastinate's queue schema and FieldRx's ``tasks`` table.

Why: planning, prescriptions and imagery ingest move out of the HTTP request
onto a PostgreSQL-backed queue (procrastinate: no new service, the same database). The
queue's own tables, types and functions are procrastinate's, applied here from the SQL
the installed package ships (``procrastinate.schema.SchemaManager.get_schema``) so the
schema still changes only through Alembic; the version applied is written in a comment
on ``procrastinate_jobs``, so a later revision that upgrades procrastinate knows which of
its ``sql/migrations`` files to apply. ``tasks`` is FieldRx's view of a job: organisation
scoping, who asked, progress 0..1 and a message, result, error, cancellation request,
batch parent.

Revision ID: 0012_tasks
Revises: 0011_cell_records
"""

from __future__ import annotations

from collections.abc import Sequence
from importlib.metadata import version

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

revision: str = "0012_tasks"
down_revision: str | Sequence[str] | None = "0011_cell_records"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

PROCRASTINATE_TABLES = (
    "procrastinate_events",
    "procrastinate_periodic_defers",
    "procrastinate_jobs",
    "procrastinate_workers",
)
PROCRASTINATE_TYPES = (
    "procrastinate_job_to_defer_v1",
    "procrastinate_job_event_type",
    "procrastinate_job_status",
)


def upgrade() -> None:
    from procrastinate.schema import SchemaManager

    # psycopg runs a parameterless multi-statement script as it is (no placeholder parsing)
    raw = op.get_bind().connection.driver_connection
    raw.execute(SchemaManager.get_schema())
    raw.execute(
        f"COMMENT ON TABLE procrastinate_jobs IS "
        f"'procrastinate {version('procrastinate')} schema (FieldRx revision 0012_tasks)'"
    )

    op.create_table(
        "tasks",
        sa.Column("id", sa.BigInteger(), nullable=False),
        sa.Column("organisation_id", sa.Integer(), nullable=False),
        sa.Column("created_by", sa.Integer(), nullable=True),
        sa.Column("parent_id", sa.BigInteger(), nullable=True),
        sa.Column("kind", sa.String(length=32), nullable=False),
        sa.Column("status", sa.String(length=16), server_default="queued", nullable=False),
        sa.Column("progress", sa.Double(), server_default=sa.text("0"), nullable=False),
        sa.Column("message", sa.Text(), server_default="", nullable=False),
        sa.Column(
            "params",
            postgresql.JSONB(astext_type=sa.Text()),
            server_default=sa.text("'{}'"),
            nullable=False,
        ),
        sa.Column("result", postgresql.JSONB(astext_type=sa.Text()), nullable=True),
        sa.Column("error", sa.Text(), nullable=True),
        sa.Column(
            "cancel_requested", sa.Boolean(), server_default=sa.text("false"), nullable=False
        ),
        sa.Column("job_id", sa.BigInteger(), nullable=True),
        sa.Column("attempts", sa.Integer(), server_default=sa.text("0"), nullable=False),
        sa.Column("worker", sa.String(length=200), server_default="", nullable=False),
        sa.Column(
            "created_at",
            sa.DateTime(timezone=True),
            server_default=sa.text("now()"),
            nullable=False,
        ),
        sa.Column(
            "updated_at",
            sa.DateTime(timezone=True),
            server_default=sa.text("now()"),
            nullable=False,
        ),
        sa.Column("started_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("finished_at", sa.DateTime(timezone=True), nullable=True),
        sa.CheckConstraint(
            "kind IN ('plan', 'prescription', 'imagery', 'plan_batch')", name="ck_tasks_kind"
        ),
        sa.CheckConstraint(
            "status IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')",
            name="ck_tasks_status",
        ),
        sa.CheckConstraint("progress >= 0 AND progress <= 1", name="ck_tasks_progress"),
        sa.ForeignKeyConstraint(["created_by"], ["users.id"], ondelete="SET NULL"),
        sa.ForeignKeyConstraint(["organisation_id"], ["organisations.id"], ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["parent_id"], ["tasks.id"], ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id"),
    )
    op.create_index("ix_tasks_org_created", "tasks", ["organisation_id", "created_at"])
    op.create_index("ix_tasks_parent", "tasks", ["parent_id"])


def downgrade() -> None:
    op.drop_index("ix_tasks_parent", table_name="tasks")
    op.drop_index("ix_tasks_org_created", table_name="tasks")
    op.drop_table("tasks")
    raw = op.get_bind().connection.driver_connection
    for table in PROCRASTINATE_TABLES:
        raw.execute(f"DROP TABLE IF EXISTS {table} CASCADE")
    functions = raw.execute(
        "SELECT p.oid::regprocedure::text FROM pg_proc p "
        "JOIN pg_namespace n ON n.oid = p.pronamespace "
        "WHERE n.nspname = current_schema() AND p.proname LIKE 'procrastinate%'"
    ).fetchall()
    for (signature,) in functions:
        raw.execute(f"DROP FUNCTION IF EXISTS {signature} CASCADE")
    for typ in PROCRASTINATE_TYPES:
        raw.execute(f"DROP TYPE IF EXISTS {typ} CASCADE")
