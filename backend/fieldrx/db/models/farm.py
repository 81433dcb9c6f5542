"""A farm's things: farms, fields (WGS84 boundary, UTM zone), machines, coverage plans
and their cells.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from geoalchemy2 import Geometry
from sqlalchemy import ARRAY, Double, ForeignKey, Integer, String, Text, text
from sqlalchemy.dialects.postgresql import JSONB
from sqlalchemy.orm import Mapped, mapped_column

from fieldrx.db.models.base import Base, now_column


class Farm(Base):
    __tablename__ = "farms"
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    name: Mapped[str] = mapped_column(String(200))
    notes: Mapped[str] = mapped_column(Text, default="")
    created_at: Mapped[dt.datetime] = now_column()


class Field(Base):
    __tablename__ = "fields"
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    farm_id: Mapped[int | None] = mapped_column(ForeignKey("farms.id", ondelete="SET NULL"))
    name: Mapped[str] = mapped_column(String(200))
    crop: Mapped[str] = mapped_column(String(100), default="")
    notes: Mapped[str] = mapped_column(Text, default="")
    boundary: Mapped[Any] = mapped_column(Geometry("MULTIPOLYGON", srid=4326, spatial_index=True))
    utm_epsg: Mapped[int] = mapped_column(Integer)
    area_m2: Mapped[float] = mapped_column(Double)
    # where an import found it ("ISOXML PFD1"): matched again on re-import
    source_ref: Mapped[str] = mapped_column(String(200), default="", server_default="")
    # kept annotations of an import (guidance lines, obstacles ...: GeoJSON features)
    features: Mapped[list[Any]] = mapped_column(
        JSONB, default=list, server_default=text("'[]'::jsonb")
    )
    created_at: Mapped[dt.datetime] = now_column()
    updated_at: Mapped[dt.datetime] = now_column()


class Machine(Base):
    __tablename__ = "machines"
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    name: Mapped[str] = mapped_column(String(200))
    implement_type: Mapped[str] = mapped_column(String(50), default="spreader")
    width_m: Mapped[float] = mapped_column(Double)
    lag_s: Mapped[float] = mapped_column(Double, default=1.52)
    calibration: Mapped[dict[str, Any]] = mapped_column(JSONB)
    controller: Mapped[dict[str, Any]] = mapped_column(JSONB, default=dict)
    antenna_forward_m: Mapped[float] = mapped_column(Double, default=0.0)
    antenna_lateral_m: Mapped[float] = mapped_column(Double, default=0.0)
    speed_min_m_s: Mapped[float] = mapped_column(Double, default=0.8)
    speed_max_m_s: Mapped[float] = mapped_column(Double, default=2.5)
    # what the implement can do beyond metering: sections, depth actuator, sensors
    capabilities: Mapped[dict[str, Any]] = mapped_column(
        JSONB, default=dict, server_default=text("'{}'::jsonb")
    )
    created_at: Mapped[dt.datetime] = now_column()


class Plan(Base):
    """A coverage plan: parameters, metrics and the route; its cells are in ``plan_cells``."""

    __tablename__ = "plans"
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    field_id: Mapped[int] = mapped_column(ForeignKey("fields.id", ondelete="CASCADE"), index=True)
    params: Mapped[dict[str, Any]] = mapped_column(JSONB)
    metrics: Mapped[dict[str, Any]] = mapped_column(JSONB, default=dict)
    heading_deg: Mapped[float] = mapped_column(Double)
    n_cells: Mapped[int] = mapped_column(Integer)
    route: Mapped[Any] = mapped_column(Geometry("LINESTRING", srid=4326, spatial_index=False))
    created_at: Mapped[dt.datetime] = now_column()


class PlanCell(Base):
    """One grid cell in path order (seed 001 Table 1): clipped polygon + the 4 UTM corners."""

    __tablename__ = "plan_cells"
    plan_id: Mapped[int] = mapped_column(
        ForeignKey("plans.id", ondelete="CASCADE"), primary_key=True
    )
    seq: Mapped[int] = mapped_column(Integer, primary_key=True)
    swath: Mapped[int] = mapped_column(Integer)
    index_in_swath: Mapped[int] = mapped_column(Integer)
    area_m2: Mapped[float] = mapped_column(Double)
    corners_utm: Mapped[list[float]] = mapped_column(ARRAY(Double))
    geom: Mapped[Any] = mapped_column(
        Geometry("GEOMETRY", srid=4326, spatial_index=True)
    )  # Polygon or MultiPolygon (a split cell stays whole, migration 0013_cells)
