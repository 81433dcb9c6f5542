"""Fields: GeoJSON Features with validated boundaries."""

from __future__ import annotations

import datetime as dt
from typing import Any, Literal

from pydantic import Field

from fieldrx.api.schemas.base import Geometry, In, Out


class FieldProps(In):
    name: str = Field(default="", max_length=200)
    farm_id: int | None = None
    crop: str = Field(default="", max_length=100)
    notes: str = Field(default="", max_length=10_000)


class FieldFeatureIn(In):
    """A GeoJSON Feature with a Polygon or MultiPolygon geometry in WGS84 lon/lat."""

    type: Literal["Feature"] = "Feature"
    id: int | str | None = Field(default=None, description="ignored (the server numbers fields)")
    bbox: list[float] | None = Field(default=None, description="ignored (computed)")
    geometry: Geometry
    properties: FieldProps = Field(default_factory=FieldProps)


class FieldPatch(In):
    geometry: Geometry | None = None
    properties: FieldProps | None = None


class FieldPropsOut(Out):
    id: int
    name: str
    farm_id: int | None
    crop: str
    notes: str
    area_m2: float
    area_ha: float
    utm_epsg: int = Field(description="EPSG code of the UTM zone the field is measured in")
    created_at: dt.datetime | None


class FieldFeature(Out):
    type: Literal["Feature"] = "Feature"
    id: int
    geometry: Geometry
    bbox: list[float] = Field(description="minlon, minlat, maxlon, maxlat")
    properties: FieldPropsOut


class FieldCollection(Out):
    type: Literal["FeatureCollection"] = "FeatureCollection"
    features: list[FieldFeature]
    total: int
    limit: int
    offset: int


class FieldImportOut(Out):
    type: Literal["FeatureCollection"] = "FeatureCollection"
    features: list[FieldFeature]
    imported: int


class FieldAnnotations(Out):
    """Features an import kept with a field (ISOXML guidance patterns, obstacle and other
    polygons, lines and points), GeoJSON lon/lat; ``properties`` name their kind, type,
    name and where in the file they came from."""

    type: Literal["FeatureCollection"] = "FeatureCollection"
    features: list[dict[str, Any]]
    source_ref: str = Field(description="where the field came from, e.g. 'ISOXML PFD2'")
