"""As-applied per-cell figures (one as-applied kernel): no schema change.

The job tiles take the report's per-cell figures from the kernel at report time
(``fleet.reports.cached_report``) instead of a table kept by ingest: the landing
place of a record's mass depends on the records after it (T_lag later), which an
incremental per-batch aggregate cannot know. This revision stays empty so the chain
keeps its numbering.

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
