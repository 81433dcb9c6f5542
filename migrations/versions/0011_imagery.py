"""Imagery: uploaded rasters (COG) per field or farm; reserved revision.

Revision ID: 0011_imagery
Revises: 0010_planner_kinematics
"""

from __future__ import annotations

from collections.abc import Sequence

revision: str = "0011_imagery"
down_revision: str | Sequence[str] | None = "0010_planner_kinematics"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    pass


def downgrade() -> None:
    pass
