"""Fleet status and grouped alerts.

Why: a machine that stops reporting must become "offline" on the live socket after the
heartbeat timeout. ``machine_status.offline_at`` records when that was
announced, so every API process and worker can sweep without announcing it twice (the
UPDATE ... RETURNING of one sweep wins) and no GET has to write. Alerts are grouped per
job and kind (list and acknowledge-all): ``ix_alerts_job_kind`` serves those queries.

Revision ID: 0006_fleet_status_alerts
Revises: 0005_calibration_flags
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0006_fleet_status_alerts"
down_revision: str | Sequence[str] | None = "0005_calibration_flags"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column(
        "machine_status", sa.Column("offline_at", sa.DateTime(timezone=True), nullable=True)
    )
    op.create_index("ix_alerts_job_kind", "alerts", ["job_id", "kind"])


def downgrade() -> None:
    op.drop_index("ix_alerts_job_kind", table_name="alerts")
    op.drop_column("machine_status", "offline_at")
