"""Machine metering calibration, prescription flags, soil imports; reserved revision.

Revision ID: 0005_calibration_flags
Revises: 0004_telemetry_streams
"""

from __future__ import annotations

from collections.abc import Sequence

revision: str = "0005_calibration_flags"
down_revision: str | Sequence[str] | None = "0004_telemetry_streams"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    pass


def downgrade() -> None:
    pass
