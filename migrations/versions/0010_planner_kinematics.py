"""Planner kinematics (turning radius, reverse): no schema change.

Reserved while the work was planned in parallel; the radius and pattern live
in the plan's existing JSON parameters and summary. Kept (empty) because
databases already stamped with this revision must keep upgrading.

Revision ID: 0010_planner_kinematics
Revises: 0009_interchange
"""

from __future__ import annotations

from collections.abc import Sequence

revision: str = "0010_planner_kinematics"
down_revision: str | Sequence[str] | None = "0009_interchange"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    pass


def downgrade() -> None:
    pass
