"""Job kinds: sensor-based topdressing (seed 000) and depth-controlled seeding (seed 002); reserved revision.

Revision ID: 0012_job_kinds
Revises: 0011_imagery
"""

from __future__ import annotations

from collections.abc import Sequence

revision: str = "0012_job_kinds"
down_revision: str | Sequence[str] | None = "0011_imagery"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    pass


def downgrade() -> None:
    pass
