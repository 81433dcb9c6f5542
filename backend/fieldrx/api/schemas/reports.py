"""As-applied reports of a job, job summaries and archives."""

from __future__ import annotations

import datetime as dt
from typing import Any, Literal

from pydantic import Field

from fieldrx.api.schemas.base import Geometry, Open, Out
from fieldrx.api.schemas.jobs import SensorKind


class CellReportOut(Out):
    """One cell's planned vs applied figures (seed 001 eq. 17-18)."""

    seq: int
    swath: int
    area_m2: float
    target_rate_kg_ha: float = Field(description="planned (prescription version)")
    n_records: int
    mean_target_rate_kg_ha: float | None = Field(description="what the agent asked for")
    mean_applied_rate_kg_ha: float | None = Field(description="mean of the records' rates")
    applied_rate_kg_ha: float = Field(description="M2 over the cell's area")
    m1_g: float
    m2_g: float
    accuracy_pct: float | None = Field(description="theta, seed 001 eq. 18")
    first_t: float | None
    last_t: float | None


class OperatorOverrideOut(Out):
    """Records written while the operator overrode the prescription (one action)."""

    action: Literal["operator_pause", "operator_rate_override", "operator_section_off"]
    records: int
    seconds: float = Field(description="sum of those records' fix periods")
    first_at: str | None
    last_at: str | None
    from_lon_lat: list[float] | None = Field(description="where the first of them was")
    to_lon_lat: list[float] | None = Field(description="where the last of them was")


class AlarmAckOut(Out):
    at: str | None
    alarms: list[str] = Field(description="the cab's alarms the operator acknowledged")
    lon_lat: list[float] | None


class OperatorEventsOut(Out):
    """What the operator did in the cab (``fieldrx_edge.cab``): overrides and acks."""

    overrides: list[OperatorOverrideOut] = Field(default_factory=list)
    alarm_acks: list[AlarmAckOut] = Field(default_factory=list)


class ReportUnit(Out):
    """The job's figures in its prescription's rate unit (the report's own are kg)."""

    rate_unit: str = Field(description="the prescription's unit (GET /rate-units)")
    kg_per_unit: float | None = Field(
        description="kg/ha in 1 rate_unit/ha: a rate in the unit is kg/ha / this; null: the "
        "product lot does not say, so the figures stay in kg"
    )
    lot: dict[str, float] = Field(description="the product lot values the unit converts through")
    total_unit: str = Field(description="what the totals count: the unit without /ha")
    planned_total: float | None
    applied_total: float | None


class AsAppliedSummary(Out):
    job_id: int
    name: str
    state: str
    machine_id: int
    implement_width_m: float
    plan_id: int
    n_cells: int
    cells_planned: int
    cells_applied: int
    coverage_pct: float
    planned_total_kg: float
    applied_total_kg: float
    applied_in_cells_kg: float
    applied_outside_cells_kg: float
    mean_accuracy_pct: float | None
    min_accuracy_pct: float | None
    time_worked_s: float
    n_records: int
    first_t: dt.datetime | None
    last_t: dt.datetime | None
    not_applied_seqs: list[int] = Field(
        description="prescribed cells where nothing landed, path order"
    )
    uplink: Literal["full", "thin"] = Field(
        default="full",
        description="where the figures came from: every 10 Hz record (full) or the thin "
        "profile's per-cell records (1 Hz track + one record per cell left)",
    )
    operator: OperatorEventsOut | None = Field(
        default=None, description="the operator's overrides and alarm acknowledgements"
    )
    field_area_m2: float = Field(default=0.0, description="the field's area")
    planned_area_m2: float = Field(default=0.0, description="area of the prescribed cells")
    applied_area_m2: float = Field(default=0.0, description="area of the cells product reached")
    never_applied_kg: float = Field(
        default=0.0, description="planned amount of the prescribed cells nothing reached"
    )
    area_basis: Literal["utm"] = Field(
        default="utm", description="every area is measured flat in the field's UTM zone"
    )
    outcome: dict[str, float | None] = Field(
        default_factory=dict,
        description="target vs applied over the prescribed cells: target_kg, applied_kg, "
        "target_kg_ha, applied_kg_ha, difference_pct, under_area_pct / over_area_pct (share "
        "of the area more than tolerance_pct below / above its target)",
    )


class AsAppliedReport(AsAppliedSummary):
    """A prescription-map job's report; ``cells`` unless ``cells=false``."""

    cells: list[CellReportOut] | None = None
    unit: ReportUnit | None = None


class KindReport(Open):
    """A sensor job's report (``fleet.seed_reports``: NDVI / depth figures and the papers'
    Table 3 beside them)."""

    job_id: int
    kind: SensorKind
    state: str
    settings: dict[str, Any]
    n_records: int


class NamedRef(Out):
    id: int
    name: str


class RxRef(Out):
    id: int | None
    version: int | None
    product: str


class JobSummaryOut(Out):
    """Compact job record for farm software: what, where, when, how much, how well."""

    job_id: int
    name: str
    state: str
    field: NamedRef | None
    machine_id: int
    prescription: RxRef
    started_at: dt.datetime | None
    ended_at: dt.datetime | None
    first_record_at: dt.datetime | None
    last_record_at: dt.datetime | None
    time_worked_s: float
    area_applied_ha: float
    field_area_ha: float
    planned_area_ha: float
    area_basis: Literal["utm"] = "utm"
    coverage_pct: float
    planned_total_kg: float
    never_applied_kg: float
    applied_total_kg: float
    applied_outside_cells_kg: float
    mean_accuracy_pct: float | None
    min_accuracy_pct: float | None
    cells_planned: int
    cells_applied: int
    unit: Literal["kg"] = "kg"


class AsAppliedCell(Out):
    type: Literal["Feature"] = "Feature"
    id: int
    geometry: Geometry | None
    properties: CellReportOut


class AsAppliedCells(Out):
    type: Literal["FeatureCollection"] = "FeatureCollection"
    features: list[AsAppliedCell]
    summary: AsAppliedSummary


class ArchiveOut(Out):
    job_id: int
    name: str
    archived_at: dt.datetime | None
    archived_by: int | None
    summary: dict[str, Any] = Field(description="GET /jobs/{id}/summary as archived")
    cells: dict[str, Any] | None = Field(
        default=None, description="GET /jobs/{id}/as-applied/cells as archived (one archive)"
    )


class ArchiveList(Out):
    items: list[ArchiveOut]
    total: int


class RawLogState(Out):
    """Where a job's full 10 Hz log stands (thin uplink): ``not requested``, ``requested``
    (the tractor sends it with its next ``fieldrx-edge upload-log``) or ``uploaded``."""

    job_id: int
    state: Literal["not requested", "requested", "uploaded"]
