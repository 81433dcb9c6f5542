"""Soil samples of a field and their uploads."""

from __future__ import annotations

import datetime as dt
from typing import Any, Literal

from pydantic import Field

from fieldrx.api.schemas.base import Geometry, Out


class SoilImportOut(Out):
    id: int
    field_id: int
    filename: str
    sha256: str
    batch: str
    n_samples: int
    n_outside: int
    outside_stored: bool
    created_by: int | None
    created_at: dt.datetime | None


class SoilImportRow(SoilImportOut):
    n_stored: int = Field(description="samples of this upload still stored")


class SoilImportList(Out):
    items: list[SoilImportRow]
    total: int


class OutsideRow(Out):
    """A sample lying outside the field (beyond the tolerance)."""

    row: int
    sample_id: str
    lon: float
    lat: float
    distance_m: float | None


class SoilImportResult(Out):
    imported: int
    import_batch: str
    import_: SoilImportOut = Field(alias="import")
    skipped: int = Field(description="bad rows left out (skip_bad_rows)")
    errors: list[dict[str, Any]] = Field(description="{row, column, message} of each bad row")
    outside: list[OutsideRow]
    n_outside: int
    outside_stored: bool
    outside_tolerance_m: float
    message: str


class SampleProps(Out):
    id: int
    sample_id: str
    depth_cm: float | None
    n_mg_kg: float | None
    p_mg_kg: float | None
    k_mg_kg: float | None
    om_pct: float | None
    ph: float | None
    ndvi: float | None
    import_batch: str
    import_id: int | None


class SampleFeature(Out):
    type: Literal["Feature"] = "Feature"
    id: int
    geometry: Geometry
    properties: SampleProps


class SampleCollection(Out):
    type: Literal["FeatureCollection"] = "FeatureCollection"
    features: list[SampleFeature]
    total: int
