"""Imagery: uploaded rasters of a field, stored as Cloud-Optimized GeoTIFFs.

Why: drone orthophotos and satellite NDVI go under every map and feed the NDVI rate
model. The raster itself lives in the imagery directory (``storage_key``); the row keeps
what the API and the tiler need without opening it (kind, band roles, resolution,
acquisition date, footprint). ``ix_imagery_field_created`` serves "the field's newest
orthophoto"; the footprint's GiST index serves overlap queries.

Revision ID: 0008_imagery
Revises: 0007_hardening
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op
from geoalchemy2 import Geometry
from sqlalchemy.dialects import postgresql

revision: str = "0008_imagery"
down_revision: str | Sequence[str] | None = "0007_hardening"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_geospatial_table(
        "imagery",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("organisation_id", sa.Integer(), nullable=False),
        sa.Column("field_id", sa.Integer(), nullable=False),
        sa.Column("kind", sa.String(length=20), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("filename", sa.String(length=255), nullable=False),
        sa.Column("storage_key", sa.String(length=255), nullable=False),
        sa.Column("acquired_on", sa.Date(), nullable=True),
        sa.Column("source_crs", sa.Text(), nullable=False),
        sa.Column("resolution_m", sa.Double(), nullable=False),
        sa.Column("width", sa.Integer(), nullable=False),
        sa.Column("height", sa.Integer(), nullable=False),
        sa.Column("band_count", sa.SmallInteger(), nullable=False),
        sa.Column("dtype", sa.String(length=20), nullable=False),
        sa.Column("bands", postgresql.JSONB(astext_type=sa.Text()), nullable=False),
        sa.Column("nodata", sa.Double(), nullable=True),
        sa.Column("size_bytes", sa.BigInteger(), nullable=False),
        sa.Column(
            "footprint",
            Geometry(
                geometry_type="MULTIPOLYGON",
                srid=4326,
                dimension=2,
                spatial_index=False,
                from_text="ST_GeomFromEWKT",
                name="geometry",
                nullable=False,
            ),
            nullable=False,
        ),
        sa.Column("created_by", sa.Integer(), nullable=True),
        sa.Column(
            "created_at",
            sa.DateTime(timezone=True),
            server_default=sa.text("now()"),
            nullable=False,
        ),
        sa.CheckConstraint(
            "kind IN ('orthophoto', 'ndvi', 'multispectral')", name="ck_imagery_kind"
        ),
        sa.ForeignKeyConstraint(["created_by"], ["users.id"], ondelete="SET NULL"),
        sa.ForeignKeyConstraint(["field_id"], ["fields.id"], ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["organisation_id"], ["organisations.id"], ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id"),
        sa.UniqueConstraint("storage_key"),
    )
    op.create_geospatial_index(
        "idx_imagery_footprint",
        "imagery",
        ["footprint"],
        unique=False,
        postgresql_using="gist",
        postgresql_ops={},
    )
    op.create_index("ix_imagery_organisation_id", "imagery", ["organisation_id"], unique=False)
    op.create_index("ix_imagery_field_created", "imagery", ["field_id", "created_at"])


def downgrade() -> None:
    op.drop_index("ix_imagery_field_created", table_name="imagery")
    op.drop_index("ix_imagery_organisation_id", table_name="imagery")
    op.drop_geospatial_index(
        "idx_imagery_footprint",
        table_name="imagery",
        postgresql_using="gist",
        column_name="footprint",
    )
    op.drop_geospatial_table("imagery")
