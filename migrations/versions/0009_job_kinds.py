"""Job kinds: sensor-based topdressing (seed 000) and depth-controlled seeding (seed 002).

Why: a job is no longer always a prescription version. ``jobs.kind`` says which
system the tractor runs; ``jobs.settings`` holds that kind's validated settings (the NDVI ->
rate curve, sensor layout, window, controller; or target depth, sensor calibration,
controller); ``jobs.plan_id`` names the planned path the sensor kinds drive (their rates
come from the sensors, not from a prescription), so ``prescription_id`` is null for them.
Telemetry gets the sensor kinds' optional fields: raw NDVI, actuator position and the
controller gains in force.

Revision ID: 0009_job_kinds
Revises: 0008_imagery
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects.postgresql import JSONB

revision: str = "0009_job_kinds"
down_revision: str | Sequence[str] | None = "0008_imagery"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

KINDS = ("prescription_map", "ndvi_topdress", "seeding_depth")
EXTRA = ("ndvi_raw", "actuator_mm", "gain_kp", "gain_ki", "gain_kd")


def upgrade() -> None:
    op.add_column(
        "jobs",
        sa.Column("kind", sa.String(32), nullable=False, server_default="prescription_map"),
    )
    op.add_column(
        "jobs", sa.Column("settings", JSONB(), nullable=False, server_default=sa.text("'{}'"))
    )
    op.add_column(
        "jobs",
        sa.Column(
            "plan_id", sa.Integer(), sa.ForeignKey("plans.id", ondelete="CASCADE"), nullable=True
        ),
    )
    op.alter_column("jobs", "prescription_id", nullable=True)
    op.alter_column("jobs", "prescription_version", nullable=True)
    op.create_check_constraint("ck_job_kind", "jobs", f"kind IN {KINDS}")
    op.create_check_constraint(
        "ck_job_source",
        "jobs",
        "(kind = 'prescription_map' AND prescription_id IS NOT NULL"
        " AND prescription_version IS NOT NULL)"
        " OR (kind <> 'prescription_map' AND plan_id IS NOT NULL)",
    )
    for name in EXTRA:
        op.add_column("telemetry", sa.Column(name, sa.Double(), nullable=True))


def downgrade() -> None:
    for name in reversed(EXTRA):
        op.drop_column("telemetry", name)
    op.execute("DELETE FROM jobs WHERE kind <> 'prescription_map'")
    op.drop_constraint("ck_job_source", "jobs", type_="check")
    op.drop_constraint("ck_job_kind", "jobs", type_="check")
    op.alter_column("jobs", "prescription_version", nullable=False)
    op.alter_column("jobs", "prescription_id", nullable=False)
    op.drop_column("jobs", "plan_id")
    op.drop_column("jobs", "settings")
    op.drop_column("jobs", "kind")
