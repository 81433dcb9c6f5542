"""organisations.agronomy and machines.capabilities: plausibility settings, implement checks.

Why: a rate map is checked against per-nutrient ceilings before it is sent, and an
organisation sets its own (a regional legal N limit) in ``organisations.agronomy``
(``{"ceilings_kg_ha": {crop key or "*": {"N": kg/ha, ...}}, "curve_share_max": 0.25}``).
A job is checked against what its machine can do: ``machines.capabilities`` holds the
implement's sections, depth actuator and sensors (``{"sections": 1, "depth_actuator":
false, "sensors": ["canopy_ndvi"]}``). Both default to ``{}`` (no organisation setting;
a machine that declares nothing beyond its meter).

Revision ID: 0017_i33_agronomy
Revises: 0016_rx_products
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects.postgresql import JSONB

revision: str = "0017_i33_agronomy"
down_revision: str | Sequence[str] | None = "0016_rx_products"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    for table, column in (("organisations", "agronomy"), ("machines", "capabilities")):
        op.add_column(
            table,
            sa.Column(column, JSONB(), nullable=False, server_default=sa.text("'{}'::jsonb")),
        )


def downgrade() -> None:
    op.drop_column("machines", "capabilities")
    op.drop_column("organisations", "agronomy")
