"""Interchange (ISOXML / Shapefile imports, as-applied export): no schema change.

Reserved while the work was planned in parallel; imports reuse farms, fields,
plans, prescriptions and jobs, and the preview/confirm step re-posts the same
files with their sha256, so nothing new is stored. Kept (empty) because
databases already stamped with this revision must keep upgrading.

Revision ID: 0009_interchange
Revises: 0008_mqtt_credentials
"""

from __future__ import annotations

from collections.abc import Sequence

revision: str = "0009_interchange"
down_revision: str | Sequence[str] | None = "0008_mqtt_credentials"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    pass


def downgrade() -> None:
    pass
