"""Jobs: a prescription version or a sensor kind bound to a machine, and its state."""

from __future__ import annotations

import datetime as dt
from typing import Annotated, Any, Literal

from fieldrx_edge.jobkinds.registry import DEFAULT_KIND, kind_of, kinds
from fieldrx_edge.jobkinds.registry import names as kind_names
from pydantic import AfterValidator, Field, WithJsonSchema

from fieldrx.api.schemas.base import In, Open, Out

State = Literal["planned", "sent", "downloaded", "running", "paused", "completed", "aborted"]



def _known_kind(v: str) -> str:
    kind_of(v)  # UnknownKind (a ValueError) names the known kinds: a 422
    return v


# a kind of fieldrx_edge.jobkinds.registry; the OpenAPI enum is the registry's list
Kind = Annotated[
    str,
    AfterValidator(_known_kind),
    WithJsonSchema({"type": "string", "enum": list(kind_names())}),
]
SensorKind = Annotated[
    str,
    WithJsonSchema(
        {"type": "string", "enum": [k.name for k in kinds() if k.rates_from == "sensors"]}
    ),
]
KIND_DOC = "; ".join(f"{k.name} ({k.source}: {k.noun})" for k in kinds())


class JobIn(In):
    kind: Kind = Field(
        default=DEFAULT_KIND,
        description=f"{KIND_DOC}; GET /jobs/kinds lists each kind's settings, units and the "
        "papers' defaults",
    )
    prescription_id: int | None = Field(
        default=None, description="kinds whose rates are the cells': the prescription"
    )
    prescription_version: int | None = Field(
        default=None,
        description="kinds whose rates are the cells': the version to apply; default current",
    )
    plan_id: int | None = Field(
        default=None, description="sensor kinds: the planned path (field, swaths) to drive"
    )
    settings: dict[str, Any] | None = Field(
        default=None,
        description="sensor kinds: settings to change from the papers' defaults (partial)",
    )
    machine_id: int
    name: str = Field(default="", max_length=200)
    confirm_flagged: bool = Field(
        default=False,
        description="send although cells have no data or lie outside the machine's meter range "
        "(without it such a job is refused with 409 listing count, area and cells)",
    )


class StateIn(In):
    state: State
    note: str = Field(default="", max_length=2000)


class EventOut(Out):
    state: str
    at: dt.datetime
    by_user_id: int | None
    by_machine_id: int | None
    note: str


class JobOut(Out):
    id: int
    name: str
    state: str
    kind: str = DEFAULT_KIND
    prescription_id: int | None
    prescription_version: int | None
    plan_id: int | None = None
    settings: dict[str, Any] = Field(default_factory=dict)
    machine_id: int
    n_cells: int
    cells_applied: int
    progress: float
    package_checksum: str
    flagged_cells: int = 0
    flagged_confirmed: bool = False
    created_by: int | None
    created_at: dt.datetime
    updated_at: dt.datetime
    events: list[EventOut] | None = None
    machine_name: str | None = Field(default=None, description="the machine's name")
    field_id: int | None = Field(default=None, description="the field the job works")
    field_name: str | None = None
    product: str | None = Field(
        default=None, description="prescription jobs: the prescription's product"
    )
    started_at: dt.datetime | None = Field(default=None, description="first 'running' event")
    ended_at: dt.datetime | None = Field(default=None, description="last completed/aborted event")


class JobList(Out):
    items: list[JobOut]
    total: int


class SettingSpecOut(Out):
    path: str = Field(description="dotted path in the settings")
    label: str
    unit: str
    default: Any = Field(description="the value the job gets unless changed")
    source: str = Field(description="where the default comes from (a paper, or FieldRx)")
    step: float | None
    options: list[str] = Field(description="the allowed values of a choice; empty: a number")


class KindInfo(Out):
    name: str
    label: str
    noun: str = Field(description="the kind in a sentence: 'a {noun} job'")
    source: str = Field(description="the paper the kind comes from")
    rates_from: Literal["cells", "sensors"] = Field(
        description="cells: a prescription's per-cell rates (the job names a prescription); "
        "sensors: decided on the go (the job names a plan and settings)"
    )
    rate_units: list[str] = Field(
        description="cells kinds: the prescription rate units its job takes (GET /rate-units)"
    )
    progress: Literal["cells", "work"]
    needs: str = Field(description="what the machine must have")
    defaults: dict[str, Any] = Field(description="the papers' settings, units in the names")
    controllers: list[str]
    settings: list[SettingSpecOut] = Field(description="the form's inputs, in order")


class KindsOut(Out):
    kinds: dict[str, KindInfo]


class DeviceStateIn(In):
    state: Literal["downloaded", "running", "paused", "completed"]
    note: str = Field(default="", max_length=2000)


class DeviceJobList(Out):
    items: list[JobOut]
    total: int


class DeviceTokenRotated(Out):
    machine_id: int
    token: str = Field(description="the new device token: shown only once")
    expires_at: dt.datetime | None


class JobPackageOut(Open):
    """``fieldrx_edge.job_package.JobPackage``: cells in path order with corners and rates, the
    implement, calibration and control settings (see the edge agent's protocol module)."""

    job_id: int
    checksum: str


class RawLogsRequested(Out):
    """Jobs of the machine whose full 10 Hz log the office asked for (thin uplink)."""

    job_ids: list[int]


class RawLogStored(Out):
    """A job's full 10 Hz log received from the tractor (gzip of JSON lines)."""

    job_id: int
    bytes: int = Field(description="gzip size received")
    records: int = Field(description="fixes (JSON lines) in the log")
