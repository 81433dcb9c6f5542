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


class TimelogPreview(Out):
    timelog: str
    records: int
    with_position: int
    first_t: float | None
    last_t: float | None
    ddis_used: list[int]
    ddis_ignored: list[int]
    mean_applied_rate_kg_ha: float | None
    logged_width_m: float | None


class JobCreated(Out):
    job_id: int
    machine_id: int
    records: int


class TimelogImportOut(Out):
    sha256: str = SHA
    timelogs: list[TimelogPreview]
    stored: bool
    width_m: float | None
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
