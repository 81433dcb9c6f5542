"""Products: an organisation's own fertilisers for prescriptions.

Why: the prescription form picks a product (name, N / P2O5 / K2O %, price per t) to
give the nutrient-balance model its N fraction and each version its nutrient and cost
figures. The defaults every organisation sees live in code
(``agronomy.products.DEFAULT_PRODUCTS``); this table holds the ones a user adds.

Revision ID: 0016_rx_products
Revises: 0015_report_tasks
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0016_rx_products"
down_revision: str | Sequence[str] | None = "0015_report_tasks"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "products",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column(
            "organisation_id",
            sa.Integer(),
            sa.ForeignKey("organisations.id", ondelete="CASCADE"),
            nullable=False,
        ),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("n_pct", sa.Double(), nullable=False),
        sa.Column("p2o5_pct", sa.Double(), nullable=False),
        sa.Column("k2o_pct", sa.Double(), nullable=False),
        sa.Column("price_per_t", sa.Double(), nullable=True),
        sa.Column(
            "created_at", sa.DateTime(timezone=True), server_default=sa.func.now(), nullable=False
        ),
        sa.UniqueConstraint("organisation_id", "name", name="uq_product_org_name"),
        sa.CheckConstraint(
            "n_pct >= 0 AND p2o5_pct >= 0 AND k2o_pct >= 0 AND n_pct + p2o5_pct + k2o_pct <= 100",
            name="ck_product_pct",
        ),
        sa.CheckConstraint("price_per_t IS NULL OR price_per_t >= 0", name="ck_product_price"),
    )
    op.create_index("ix_products_organisation_id", "products", ["organisation_id"])


def downgrade() -> None:
    op.drop_index("ix_products_organisation_id", table_name="products")
    op.drop_table("products")
