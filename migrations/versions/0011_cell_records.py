"""Cell records of the thin uplink profile: per-cell as-applied results, kept forever.

Why: with uplink profile ``thin`` a machine sends a 1 Hz track plus one record
per cell it left (``fieldrx_edge.protocol.CellRecord``: the cell's landed mass, driven
length, entry/exit time, worked time, mean speed and rates, alarms), computed on the
tractor by the one as-applied kernel over its 10 Hz log. The job report of a thin job is
built from them. They live in their own table, not in ``telemetry``: telemetry is
partitioned by day and dropped after its retention, the per-cell results are kept.

Keyed like telemetry by (machine, stream, seq) -- the cell records travel on their own
stream with the same deduplication and acknowledgement -- so the table can be
distributed by machine (Citus) with telemetry; reports read it by (job, cell).
``cell_record_streams`` holds each cell stream's acknowledged seq (``telemetry_streams``
for cell streams: kept apart so a thin agent's two streams are not two agents).

Revision ID: 0011_cell_records
Revises: 0010_telemetry_partitions
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects.postgresql import ARRAY

revision: str = "0011_cell_records"
down_revision: str | Sequence[str] | None = "0010_telemetry_partitions"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "job_cell_records",
        sa.Column(
            "machine_id",
            sa.Integer(),
            sa.ForeignKey("machines.id", ondelete="CASCADE"),
            primary_key=True,
        ),
        sa.Column("stream", sa.String(32), primary_key=True),
        sa.Column("seq", sa.BigInteger(), primary_key=True),
        sa.Column(
            "job_id", sa.Integer(), sa.ForeignKey("jobs.id", ondelete="CASCADE"), nullable=False
        ),
        sa.Column("cell_seq", sa.Integer(), nullable=True),
        sa.Column("t_entry", sa.DateTime(timezone=True), nullable=False),
        sa.Column("t_exit", sa.DateTime(timezone=True), nullable=False),
        sa.Column("n_fixes", sa.Integer(), nullable=False),
        sa.Column("worked_s", sa.Double(), nullable=False),
        sa.Column("mass_g", sa.Double(), nullable=False),
        sa.Column("driven_m", sa.Double(), nullable=True),
        sa.Column("mean_speed_m_s", sa.Double(), nullable=True),
        sa.Column("mean_target_rate_kg_ha", sa.Double(), nullable=True),
        sa.Column("mean_applied_rate_kg_ha", sa.Double(), nullable=True),
        sa.Column("flags", ARRAY(sa.String(32)), nullable=False, server_default="{}"),
        sa.Column(
            "received_at", sa.DateTime(timezone=True), nullable=False, server_default=sa.func.now()
        ),
    )
    op.create_index("ix_job_cell_records_job_cell", "job_cell_records", ["job_id", "cell_seq"])
    op.create_table(
        "cell_record_streams",
        sa.Column(
            "machine_id",
            sa.Integer(),
            sa.ForeignKey("machines.id", ondelete="CASCADE"),
            primary_key=True,
        ),
        sa.Column("stream", sa.String(32), primary_key=True),
        sa.Column("first_seq", sa.BigInteger(), nullable=False),
        sa.Column("acked_seq", sa.BigInteger(), nullable=False),
        sa.Column("n_records", sa.BigInteger(), nullable=False),
        sa.Column(
            "first_seen_at",
            sa.DateTime(timezone=True),
            nullable=False,
            server_default=sa.func.now(),
        ),
        sa.Column(
            "last_seen_at",
            sa.DateTime(timezone=True),
            nullable=False,
            server_default=sa.func.now(),
        ),
    )


def downgrade() -> None:
    op.drop_table("cell_record_streams")
    op.drop_index("ix_job_cell_records_job_cell", table_name="job_cell_records")
    op.drop_table("job_cell_records")
