"""Soil samples of a field and their uploads."""

from __future__ import annotations

import datetime as dt
from typing import Any, Literal

from pydantic import Field

from fieldrx.agronomy.soil_lab import DEFAULT_BULK_DENSITY_G_CM3
from fieldrx.api.schemas.base import Geometry, In, Out


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
    replaced: int = Field(default=0, description="earlier samples deleted (mode=replace)")
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


LabTarget = Literal["sample_id", "x", "y", "depth", "n", "p", "k", "om", "ph"]


NForm = Literal["alkali_hydrolysable", "mineral", "total"]


class SoilMappingIn(In):
    """How a lab file's columns are read (sent as the JSON text of the ``mapping`` form field).

    ``columns``: quantity -> the file's column name; ``x``/``y`` are easting/northing or
    longitude/latitude, as ``epsg`` says. ``units``: quantity -> one of the units the
    preview lists for it (``targets[].units``), converted to the stored unit."""

    columns: dict[LabTarget, str]
    units: dict[LabTarget, str] = Field(default_factory=dict)
    epsg: int | None = Field(default=None, description="EPSG code of x/y (4326 = lon/lat)")
    bulk_density_g_cm3: float = Field(
        default=DEFAULT_BULK_DENSITY_G_CM3,
        ge=0.5,
        le=2.5,
        description="soil bulk density for Nmin kg/ha -> mg/kg",
    )
    n_form: NForm = Field(
        default="alkali_hydrolysable",
        description="which N the N column holds: alkali_hydrolysable (seed 001's soil N, the "
        "nutrient-balance model's input), mineral (Nmin) or total N",
    )


class SoilMappingOut(Out):
    columns: dict[str, str]
    units: dict[str, str]
    epsg: int | None
    bulk_density_g_cm3: float
    n_form: NForm = Field(default="alkali_hydrolysable", description="which N the N column holds")


class LabColumn(Out):
    name: str
    examples: list[str] = Field(description="the first values of the column, as in the file")
    target: str | None = Field(description="quantity it is mapped to (None: not read)")


class LabTargetOut(Out):
    target: str
    label: str
    stored_unit: str
    units: list[str] = Field(description="units a column of this quantity may be in")
    default_unit: str


class CrsOption(Out):
    epsg: int
    name: str


class RowProblem(Out):
    """A rejected row (``row`` = record number, header = 1) or a mapping problem (row 1)."""

    row: int
    column: str | None
    message: str
    kind: str


class LabSampleRow(Out):
    """One accepted row, converted: lon/lat WGS84, stored units."""

    row: int
    sample_id: str
    lon: float
    lat: float
    depth_cm: float
    n_mg_kg: float | None
    p_mg_kg: float | None
    k_mg_kg: float | None
    om_g_kg: float | None
    ph: float | None


class SoilLabPreview(Out):
    """What confirming the file with this mapping would store (nothing is stored)."""

    filename: str
    delimiter: str
    encoding: str
    decimal_comma: bool
    columns: list[LabColumn]
    targets: list[LabTargetOut]
    crs_options: list[CrsOption]
    suggested: SoilMappingOut = Field(description="the mapping read from the headers")
    mapping: SoilMappingOut = Field(description="the mapping this preview applied")
    mapping_ok: bool = Field(description="False: the mapping itself is wrong (see rejected)")
    n_rows: int
    n_accepted: int
    n_inside: int
    n_rejected: int
    rejected: list[RowProblem]
    n_outside: int
    outside: list[OutsideRow]
    outside_tolerance_m: float
    rows: list[LabSampleRow] = Field(description="the first accepted rows, converted")
    n_existing: int = Field(description="samples the field has now (mode=replace deletes them)")
