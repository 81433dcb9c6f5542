"""What is measured on a field and feeds a prescription: soil imports and their
samples, and uploaded imagery.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from geoalchemy2 import Geometry
from sqlalchemy import (
    BigInteger,
    Boolean,
    CheckConstraint,
    Date,
    Double,
    ForeignKey,
    Index,
    Integer,
    SmallInteger,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.dialects.postgresql import JSONB
from sqlalchemy.orm import Mapped, mapped_column

from fieldrx.db.models.base import Base, now_column


class SoilImport(Base):
    """One uploaded soil file: its samples are deleted with it; the same bytes twice are refused."""

    __tablename__ = "soil_imports"
    __table_args__ = (UniqueConstraint("field_id", "sha256", name="uq_soil_imports_field_sha256"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    field_id: Mapped[int] = mapped_column(ForeignKey("fields.id", ondelete="CASCADE"), index=True)
    filename: Mapped[str] = mapped_column(String(255), default="")
    sha256: Mapped[str] = mapped_column(String(71))
    batch: Mapped[str] = mapped_column(String(64), default="")
    n_samples: Mapped[int] = mapped_column(Integer, default=0)
    n_outside: Mapped[int] = mapped_column(Integer, default=0)
    outside_stored: Mapped[bool] = mapped_column(Boolean, default=False)
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    created_at: Mapped[dt.datetime] = now_column()


class SoilSample(Base):
    __tablename__ = "soil_samples"
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    field_id: Mapped[int] = mapped_column(ForeignKey("fields.id", ondelete="CASCADE"), index=True)
    sample_id: Mapped[str] = mapped_column(String(100))
    depth_cm: Mapped[float | None] = mapped_column(Double)
    n_mg_kg: Mapped[float | None] = mapped_column(Double)
    p_mg_kg: Mapped[float | None] = mapped_column(Double)
    k_mg_kg: Mapped[float | None] = mapped_column(Double)
    om_pct: Mapped[float | None] = mapped_column(Double)
    ph: Mapped[float | None] = mapped_column(Double)
    ndvi: Mapped[float | None] = mapped_column(Double)
    # which N n_mg_kg is (agronomy.soil.N_FORMS): the nutrient-balance model reads only
    # alkali-hydrolysable N (seed 001 eq. 19-21)
    n_form: Mapped[str] = mapped_column(
        String(24), default="alkali_hydrolysable", server_default="alkali_hydrolysable"
    )
    geom: Mapped[Any] = mapped_column(Geometry("POINT", srid=4326, spatial_index=True))
    import_batch: Mapped[str] = mapped_column(String(64), default="")
    import_id: Mapped[int | None] = mapped_column(
        ForeignKey("soil_imports.id", ondelete="CASCADE"), index=True
    )
    created_at: Mapped[dt.datetime] = now_column()


IMAGERY_KINDS = ("orthophoto", "ndvi", "multispectral")


class Imagery(Base):
    """An uploaded raster of a field, stored as a Cloud-Optimized GeoTIFF.

    ``storage_key`` is the COG's path relative to the imagery directory; ``bands`` maps
    roles to 1-based band numbers (``{"red": 3, "nir": 4}``, ``{"ndvi": 1}``,
    ``{"r": 1, "g": 2, "b": 3}``); ``footprint`` is the raster's outline in WGS84.
    """

    __tablename__ = "imagery"
    __table_args__ = (
        CheckConstraint("kind IN ('orthophoto', 'ndvi', 'multispectral')", name="ck_imagery_kind"),
        Index("ix_imagery_field_created", "field_id", "created_at"),
    )
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    field_id: Mapped[int] = mapped_column(ForeignKey("fields.id", ondelete="CASCADE"))
    kind: Mapped[str] = mapped_column(String(20))
    name: Mapped[str] = mapped_column(String(200), default="")
    filename: Mapped[str] = mapped_column(String(255), default="")
    storage_key: Mapped[str] = mapped_column(String(255), unique=True)
    acquired_on: Mapped[dt.date | None] = mapped_column(Date)
    source_crs: Mapped[str] = mapped_column(Text, default="")
    resolution_m: Mapped[float] = mapped_column(Double)
    width: Mapped[int] = mapped_column(Integer)
    height: Mapped[int] = mapped_column(Integer)
    band_count: Mapped[int] = mapped_column(SmallInteger)
    dtype: Mapped[str] = mapped_column(String(20))
    bands: Mapped[dict[str, Any]] = mapped_column(JSONB, default=dict)
    nodata: Mapped[float | None] = mapped_column(Double)
    size_bytes: Mapped[int] = mapped_column(BigInteger)
    footprint: Mapped[Any] = mapped_column(Geometry("MULTIPOLYGON", srid=4326, spatial_index=True))
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    created_at: Mapped[dt.datetime] = now_column()
