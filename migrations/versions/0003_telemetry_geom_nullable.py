"""telemetry.geom nullable: a record without a fix (lon/lat null) is still a record.

Why: the wire format (fieldrx_edge.protocol.TelemetryRecord) allows lon and
lat to be null when the receiver has no fix; those records carry the fix-lost
state, the motor and the queue backlog, and must be stored (the fix_lost alert
and the zero-loss guarantee depend on them).

Revision ID: 0003_telemetry_geom_nullable
Revises: 0002_plan_cells_partitioned
"""

from __future__ import annotations

from collections.abc import Sequence

from alembic import op

revision: str = "0003_telemetry_geom_nullable"
down_revision: str | Sequence[str] | None = "0002_plan_cells_partitioned"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.alter_column("telemetry", "geom", nullable=True)


def downgrade() -> None:
    op.execute("DELETE FROM telemetry WHERE geom IS NULL")
    op.alter_column("telemetry", "geom", nullable=False)
