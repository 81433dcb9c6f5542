"""Hardening: archived job evidence that outlives its machine/field/plan, login throttling.

Why: deleting a machine, field, plan or prescription cascaded to its jobs and
silently erased their as-applied records. Deletion is now refused
while a job with as-applied data is not archived; archiving copies the job's
as-applied summary and per-cell records into ``job_archives``, which hangs
only off the organisation, so it outlives whatever the job was made from.
``login_failures`` counts failed sign-ins per account and per address for
throttling (shared by every API process).

Revision ID: 0007_hardening
Revises: 0006_fleet_status_alerts
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

revision: str = "0007_hardening"
down_revision: str | Sequence[str] | None = "0006_fleet_status_alerts"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "job_archives",
        sa.Column("job_id", sa.Integer(), primary_key=True, autoincrement=False),
        sa.Column(
            "organisation_id",
            sa.Integer(),
            sa.ForeignKey("organisations.id", ondelete="CASCADE"),
            nullable=False,
        ),
        sa.Column("name", sa.String(200), nullable=False, server_default=""),
        sa.Column(
            "archived_at", sa.DateTime(timezone=True), server_default=sa.func.now(), nullable=False
        ),
        sa.Column("archived_by", sa.Integer(), sa.ForeignKey("users.id", ondelete="SET NULL")),
        sa.Column("summary", postgresql.JSONB(), nullable=False),
        sa.Column("cells", postgresql.JSONB(), nullable=False),
    )
    op.create_index("ix_job_archives_organisation_id", "job_archives", ["organisation_id"])
    op.create_table(
        "login_failures",
        sa.Column("id", sa.BigInteger(), primary_key=True),
        sa.Column("key", sa.String(400), nullable=False),
        sa.Column("at", sa.DateTime(timezone=True), server_default=sa.func.now(), nullable=False),
    )
    op.create_index("ix_login_failures_key_at", "login_failures", ["key", "at"])


def downgrade() -> None:
    op.drop_index("ix_login_failures_key_at", table_name="login_failures")
    op.drop_table("login_failures")
    op.drop_index("ix_job_archives_organisation_id", table_name="job_archives")
    op.drop_table("job_archives")
