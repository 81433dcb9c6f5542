"""organisations.agronomy, machines.capabilities, soil_samples.n_form: agronomic checks.

Why: a rate map is checked against per-nutrient ceilings before it is sent, and an
organisation sets its own (a regional legal N limit) in ``organisations.agronomy``
(``{"ceilings_kg_ha": {crop key or "*": {"N": kg/ha, ...}}, "curve_share_max": 0.25}``).
A job is checked against what its machine can do: ``machines.capabilities`` holds the
implement's sections, depth actuator and sensors (``{"sections": 1, "depth_actuator":
false, "sensors": ["canopy_ndvi"]}``). Both default to ``{}`` (no organisation setting;
a machine that declares nothing beyond its meter). ``soil_samples.n_form`` says which N a
sample's ``n_mg_kg`` is (alkali-hydrolysable, mineral, total): seed 001's model reads only
the first; samples stored before are the plain import's alkali-hydrolysable N.

Revision ID: 0017_i33_agronomy
Revises: 0017_i30_product_density
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects.postgresql import JSONB

revision: str = "0017_i33_agronomy"
down_revision: str | Sequence[str] | None = "0017_i30_product_density"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    for table, column in (("organisations", "agronomy"), ("machines", "capabilities")):
        op.add_column(
            table,
            sa.Column(column, JSONB(), nullable=False, server_default=sa.text("'{}'::jsonb")),
        )
    op.add_column(
        "soil_samples",
        sa.Column("n_form", sa.String(24), nullable=False, server_default="alkali_hydrolysable"),
    )


def downgrade() -> None:
    op.drop_column("soil_samples", "n_form")
    op.drop_column("machines", "capabilities")
    op.drop_column("organisations", "agronomy")
