"""fields: the partfield id an import came from, and its kept annotations.

Why: a TASKDATA set imported twice must find its fields again (by ISOXML partfield
id as well as by name and geometry), and a partfield's guidance lines, obstacles and
annotations (PLN types 2-12, GGP, LSG, PNT) are kept with the field instead of dropped.

Revision ID: 0017_i32_field_features
Revises: 0017_i33_agronomy
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects.postgresql import JSONB

revision: str = "0017_i32_field_features"
down_revision: str | Sequence[str] | None = "0017_i33_agronomy"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column(
        "fields",
        sa.Column("source_ref", sa.String(200), nullable=False, server_default=""),
    )
    op.add_column(
        "fields",
        sa.Column("features", JSONB(), nullable=False, server_default=sa.text("'[]'::jsonb")),
    )


def downgrade() -> None:
    op.drop_column("fields", "features")
    op.drop_column("fields", "source_ref")
