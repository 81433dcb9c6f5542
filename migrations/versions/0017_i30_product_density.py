"""products.density_kg_l: a liquid product's density, carried into job packages.

Why: an ISOBUS volume-rate implement (DDI 1, l/ha) takes a kg/ha prescription only through
the product's density; it belongs to the product, not to a number typed in the cab. NULL
for solids (and for liquids whose density is not known: then nothing is converted).

Revision ID: 0017_i30_product_density
Revises: 0016_rx_products
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0017_i30_product_density"
down_revision: str | Sequence[str] | None = "0016_rx_products"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column("products", sa.Column("density_kg_l", sa.Double(), nullable=True))
    op.create_check_constraint(
        "ck_product_density",
        "products",
        "density_kg_l IS NULL OR (density_kg_l >= 0.05 AND density_kg_l <= 5)",
    )


def downgrade() -> None:
    op.drop_constraint("ck_product_density", "products", type_="check")
    op.drop_column("products", "density_kg_l")
