"""Imagery of a field (GeoTIFF stored as COG) and prescriptions made from it."""

from __future__ import annotations

import datetime as dt
from typing import Any, Literal

from pydantic import Field

from fieldrx.api.schemas.base import Geometry, In, Out


class ImageryOut(Out):
    id: int
    field_id: int
    kind: Literal["orthophoto", "ndvi", "multispectral"]
    name: str
    filename: str
    acquired_on: dt.date | None
    source_crs: str
    resolution_m: float
    width: int
    height: int
    band_count: int
    dtype: str
    bands: dict[str, Any]
    nodata: float | None
    size_bytes: int
    bounds: list[float] = Field(description="minlon, minlat, maxlon, maxlat")
    footprint: Geometry
    tiles: str = Field(description="PNG tile URL template")
    created_at: dt.datetime | None


class ImageryUploadOut(ImageryOut):
    overlap_share: float = Field(description="share of the field the image covers")
    warnings: list[str]


class ImageryList(Out):
    items: list[ImageryOut]
    total: int


class ImageryRxIn(In):
    """An NDVI prescription whose per-cell NDVI comes from an image (not from samples)."""

    plan_id: int
    name: str = Field(default="", max_length=200)
    product: str = Field(default="", max_length=200)
    params: dict[str, Any] = Field(
        default_factory=dict,
        description="seed 000 NDVI curve: ndvi_low, rate_at_low_kg_ha, ndvi_high, "
        "rate_at_high_kg_ha (defaults 0.24 -> 375, 0.65 -> 180 kg/ha)",
    )
    min_valid_share: float = Field(
        default=0.5, ge=0, le=1, description="cells with fewer valid pixels have no data"
    )
    fallback_rate_kg_ha: float | None = Field(default=None, ge=0)
    machine_id: int | None = None
    speed_min_kmh: float | None = Field(default=None, gt=0)
    speed_max_kmh: float | None = Field(default=None, gt=0)
    width_m: float | None = Field(default=None, gt=0)
    calibration: dict[str, Any] | None = None


class ZonesIn(ImageryRxIn):
    k: int = Field(default=4, ge=2, le=12, description="number of zones")
    min_area_m2: float = Field(
        default=0.0, ge=0, description="patches of a zone smaller than this join a neighbour"
    )
