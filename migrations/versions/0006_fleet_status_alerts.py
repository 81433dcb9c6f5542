"""Fleet status and grouped alerts; reserved revision.

Revision ID: 0006_fleet_status_alerts
Revises: 0005_calibration_flags
"""

from __future__ import annotations

from collections.abc import Sequence

revision: str = "0006_fleet_status_alerts"
down_revision: str | Sequence[str] | None = "0005_calibration_flags"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    pass


def downgrade() -> None:
    pass
