"""As-applied per-cell figures kept by ingest (one as-applied kernel); reserved revision.

Revision ID: 0013_asapplied_cells
Revises: 0012_job_kinds
"""

from __future__ import annotations

from collections.abc import Sequence

revision: str = "0013_asapplied_cells"
down_revision: str | Sequence[str] | None = "0012_job_kinds"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    pass


def downgrade() -> None:
    pass
