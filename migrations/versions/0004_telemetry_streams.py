"""Telemetry streams: deduplicate by (machine, stream, seq); reserved revision.

Revision ID: 0004_telemetry_streams
Revises: 0003_telemetry_geom_nullable
"""

from __future__ import annotations

from collections.abc import Sequence

revision: str = "0004_telemetry_streams"
down_revision: str | Sequence[str] | None = "0003_telemetry_geom_nullable"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    pass


def downgrade() -> None:
    pass
