"""Telemetry streams: deduplicate by (machine, stream, seq).

Why: telemetry was deduplicated by (machine_id, seq). An agent whose
queue is lost (new tablet, wiped state dir, a simulation without --state-dir)
numbers from 1 again, and the server acknowledged and dropped every record it
already had a seq for. Each agent queue now has a random stream id sent with
every batch (fieldrx_edge.protocol, telemetry format 2):

* ``telemetry.stream`` joins the primary key: (machine_id, stream, seq).
  Records stored before streams, and batches of agents that send no stream,
  are the machine's legacy stream ''.
* ``telemetry.fix_period_s``: the fix period a record stands for; the
  as-applied report integrates metered mass over it (defect 2).
* ``telemetry_streams``: one row per (machine, stream) with the stream's
  acknowledged seq (``machine_status.acked_seq`` was the only one) and what
  the fleet view shows about it (first/last seen, records, record time span).
  The legacy stream of each machine is created from ``machine_status``.

Revision ID: 0004_telemetry_streams
Revises: 0003_telemetry_geom_nullable
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0004_telemetry_streams"
down_revision: str | Sequence[str] | None = "0003_telemetry_geom_nullable"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column(
        "telemetry", sa.Column("stream", sa.String(32), server_default="", nullable=False)
    )
    op.add_column("telemetry", sa.Column("fix_period_s", sa.Double(), nullable=True))
    op.drop_constraint("telemetry_pkey", "telemetry", type_="primary")
    op.create_primary_key("telemetry_pkey", "telemetry", ["machine_id", "stream", "seq"])
    op.create_table(
        "telemetry_streams",
        sa.Column("machine_id", sa.Integer(), nullable=False),
        sa.Column("stream", sa.String(32), nullable=False),
        sa.Column("first_seq", sa.BigInteger(), nullable=False),
        sa.Column("acked_seq", sa.BigInteger(), nullable=False),
        sa.Column("n_records", sa.BigInteger(), nullable=False),
        sa.Column(
            "first_seen_at", sa.DateTime(timezone=True), server_default=sa.text("now()"),
            nullable=False,
        ),
        sa.Column(
            "last_seen_at", sa.DateTime(timezone=True), server_default=sa.text("now()"),
            nullable=False,
        ),
        sa.Column("first_t", sa.DateTime(timezone=True), nullable=True),
        sa.Column("last_t", sa.DateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(["machine_id"], ["machines.id"], ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("machine_id", "stream"),
    )  # fmt: skip
    op.execute(
        """
        INSERT INTO telemetry_streams (machine_id, stream, first_seq, acked_seq, n_records,
            first_seen_at, last_seen_at, first_t, last_t)
        SELECT s.machine_id, '', 1, s.acked_seq, coalesce(t.n, 0),
            coalesce(s.last_seen_at, now()), coalesce(s.last_seen_at, now()), t.first_t, t.last_t
        FROM machine_status s
        LEFT JOIN (SELECT machine_id, count(*) AS n, min(t) AS first_t, max(t) AS last_t
                   FROM telemetry GROUP BY machine_id) t USING (machine_id)
        """
    )


def downgrade() -> None:
    op.drop_table("telemetry_streams")
    # (machine_id, seq) cannot hold two streams: keep the legacy stream's records only
    op.execute("DELETE FROM telemetry WHERE stream <> ''")
    op.drop_constraint("telemetry_pkey", "telemetry", type_="primary")
    op.create_primary_key("telemetry_pkey", "telemetry", ["machine_id", "seq"])
    op.drop_column("telemetry", "fix_period_s")
    op.drop_column("telemetry", "stream")
