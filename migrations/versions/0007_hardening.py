"""Hardening: device token expiry, archived evidence, login throttling; reserved revision.

Revision ID: 0007_hardening
Revises: 0006_fleet_status_alerts
"""

from __future__ import annotations

from collections.abc import Sequence

revision: str = "0007_hardening"
down_revision: str | Sequence[str] | None = "0006_fleet_status_alerts"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    pass


def downgrade() -> None:
    pass
