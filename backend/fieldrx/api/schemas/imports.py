"""Imports of other software's files: each answers a preview first, then (with ``confirm`` =
the preview's sha256) stores everything or nothing."""

from __future__ import annotations

from typing import Any

from pydantic import Field

from fieldrx.api.schemas.base import Out

SHA = Field(description="digest of the upload: send it back as ``confirm`` to store")


class IsoxmlImportOut(Out):
    sha256: str = SHA
    preview: dict[str, Any] = Field(
        description="what a confirmed import creates (version, farms, fields, prescriptions) "
        "and what it skips and why"
    )
    stored: bool
    created: dict[str, Any] | None = Field(
        default=None, description="ids created: farms, fields [{id, ref, name}], prescriptions"
    )


class RxMapping(Out):
    rate_column: str
    unit: str
    min_rate_kg_ha: float
    max_rate_kg_ha: float
    default_rate_kg_ha: float
    overlap_pct: float | None = Field(default=None, description="share of the field covered")
    distance_m: float | None = Field(
        default=None, description="zones' distance from the field (> 0: refused on confirm)"
    )
    warning: str | None = None


class RxCreated(Out):
    prescription_id: int
    plan_id: int
    field_id: int


class RxShapefileImportOut(Out):
    sha256: str = SHA
    features: int
    numeric_columns: dict[str, dict[str, float]] = Field(
        description="columns whose every value is a number: count, min, max"
    )
    suggested_rate_column: str | None
    units: list[str]
    stored: bool
    mapping: RxMapping | None = None
    created: RxCreated | None = None


class TimelogPlacement(Out):
    on_field: int = Field(description="records whose position lies on the prescription's field")
    with_position: int
    distance_m: float | None = Field(description="nearest record's distance (0 when on it)")


class TimelogPreview(Out):
    timelog: str
    records: int
    with_position: int
    first_t: float | None
    last_t: float | None
    centre: list[float] | None = Field(description="median lon, lat of the records")
    ddis_used: list[int]
    ddis_ignored: list[int]
    reported: dict[str, int] = Field(description="DDI -> number of records reporting it")
    totals: dict[str, Any] = Field(
        default_factory=dict, description="total counters (DDI -> name, unit, growth over the log)"
    )
    has_rate: bool = Field(description="the log carries an applied rate (DDI 7)")
    gives: str = Field(description="what FieldRx can make of the log")
    mean_applied_rate_kg_ha: float | None
    logged_width_m: float | None
    placement: TimelogPlacement | None = None


class JobCreated(Out):
    job_id: int
    machine_id: int
    records: int


class TimelogImportOut(Out):
    sha256: str = SHA
    timelogs: list[TimelogPreview]
    stored: bool
    width_m: float | None
    refused: list[str] = Field(
        default_factory=list, description="logs that lie off the field: confirm is refused"
    )
    created: JobCreated | None = None


class TableMapping(Out):
    records: int
    mean_applied_rate_kg_ha: float
    mean_speed_m_s: float
    times: str


class AsAppliedTableImportOut(Out):
    sha256: str = SHA
    columns: list[str]
    numeric: dict[str, dict[str, float]] = Field(description="numeric columns: {min, max}")
    suggested: dict[str, str | None] = Field(description="a suggested column per mapping field")
    rows: int
    stored: bool
    mapping: TableMapping | None = None
    created: JobCreated | None = None
