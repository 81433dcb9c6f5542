"""Prescriptions: the prescription, its immutable versions and per-cell rates, and the
product catalogue.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from sqlalchemy import (
    ARRAY,
    CheckConstraint,
    Double,
    ForeignKey,
    Integer,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.dialects.postgresql import JSONB
from sqlalchemy.orm import Mapped, mapped_column

from fieldrx.db.models.base import Base, now_column


class Prescription(Base):
    __tablename__ = "prescriptions"
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    plan_id: Mapped[int] = mapped_column(ForeignKey("plans.id", ondelete="CASCADE"), index=True)
    # no foreign key into the distributed machines (migration 0017); unset on its delete
    machine_id: Mapped[int | None] = mapped_column(Integer)
    name: Mapped[str] = mapped_column(String(200), default="")
    product: Mapped[str] = mapped_column(String(200), default="")
    model: Mapped[str] = mapped_column(String(50))
    params: Mapped[dict[str, Any]] = mapped_column(JSONB, default=dict)
    current_version: Mapped[int] = mapped_column(Integer, default=1)
    created_at: Mapped[dt.datetime] = now_column()


class Product(Base):
    """A fertiliser an organisation added to its catalogue (the defaults every
    organisation sees are in ``agronomy.products.DEFAULT_PRODUCTS``, not rows)."""

    __tablename__ = "products"
    __table_args__ = (
        UniqueConstraint("organisation_id", "name", name="uq_product_org_name"),
        CheckConstraint(
            "n_pct >= 0 AND p2o5_pct >= 0 AND k2o_pct >= 0 AND n_pct + p2o5_pct + k2o_pct <= 100",
            name="ck_product_pct",
        ),
        CheckConstraint("price_per_t IS NULL OR price_per_t >= 0", name="ck_product_price"),
        CheckConstraint(
            "density_kg_l IS NULL OR (density_kg_l >= 0.05 AND density_kg_l <= 5)",
            name="ck_product_density",
        ),
    )
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    name: Mapped[str] = mapped_column(String(200))
    n_pct: Mapped[float] = mapped_column(Double)
    p2o5_pct: Mapped[float] = mapped_column(Double, default=0.0)
    k2o_pct: Mapped[float] = mapped_column(Double, default=0.0)
    price_per_t: Mapped[float | None] = mapped_column(Double)
    # a liquid's density (kg/l), for ISOBUS volume-rate implements; NULL for solids
    density_kg_l: Mapped[float | None] = mapped_column(Double)
    created_at: Mapped[dt.datetime] = now_column()


class PrescriptionVersion(Base):
    """An immutable version; an edit creates version n+1 and leaves n as it was."""

    __tablename__ = "prescription_versions"
    __table_args__ = (UniqueConstraint("prescription_id", "version"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    prescription_id: Mapped[int] = mapped_column(
        ForeignKey("prescriptions.id", ondelete="CASCADE"), index=True
    )
    version: Mapped[int] = mapped_column(Integer)
    note: Mapped[str] = mapped_column(Text, default="")
    summary: Mapped[dict[str, Any]] = mapped_column(JSONB, default=dict)
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    created_at: Mapped[dt.datetime] = now_column()


class PrescriptionRate(Base):
    __tablename__ = "prescription_rates"
    version_id: Mapped[int] = mapped_column(
        ForeignKey("prescription_versions.id", ondelete="CASCADE"), primary_key=True
    )
    seq: Mapped[int] = mapped_column(Integer, primary_key=True)
    rate_kg_ha: Mapped[float] = mapped_column(Double)
    source_value: Mapped[float | None] = mapped_column(Double)  # interpolated N mg/kg or NDVI
    flags: Mapped[list[str]] = mapped_column(ARRAY(String(32)), default=list)
