"""Fleet view: machine status, alerts, track replay, chart columns."""

from __future__ import annotations

import datetime as dt
from typing import Literal

from pydantic import Field

from fieldrx.api.schemas.base import Feature, Geometry, In, Out


class StatusJob(Out):
    id: int
    name: str
    state: str
    cells_applied: int
    n_cells: int
    progress: float = Field(description="cells_applied / n_cells, 0..1")


class MachineStatus(Out):
    """A machine's present state (``fleet.status.machine_status``); the live socket's
    ``status`` message carries the same objects."""

    machine_id: int
    name: str
    online: bool
    state: Literal["offline", "alarm", "working", "moving", "idle"]
    last_seen_at: dt.datetime | None
    silent_s: float | None = Field(description="seconds since the last record")
    last_t: dt.datetime | None = Field(description="time of the last record")
    acked_seq: int
    position: Geometry | None = Field(description="GeoJSON Point of the last fix")
    speed_m_s: float | None = Field(description="present speed (null when offline)")
    last_speed_m_s: float | None = Field(description="speed of the last record, even offline")
    heading_deg: float | None
    speed_range_m_s: list[float | None]
    job: StatusJob | None
    cell_seq: int | None
    target_rate_kg_ha: float | None
    applied_rate_kg_ha: float | None
    rate_error_pct: float | None
    queue_backlog: int
    alarms: list[str]
    active_alerts: int | None


class FleetStatusOut(Out):
    heartbeat_timeout_s: float
    server_time: dt.datetime
    items: list[MachineStatus]


class AlertOut(Out):
    id: int
    machine_id: int
    job_id: int | None
    kind: str
    message: str
    value: float | None
    started_at: dt.datetime
    ended_at: dt.datetime | None
    active: bool = Field(description="not ended")
    acknowledged_at: dt.datetime | None
    acknowledged_by: int | None


class AlertList(Out):
    items: list[AlertOut]
    total: int


class AlertGroup(Out):
    """Alerts of one kind on one job (machine and kind without a job)."""

    machine_id: int
    job_id: int | None
    kind: str
    count: int
    active: int = Field(description="alerts of the group not ended")
    unacknowledged: int
    acknowledged: bool = Field(description="every alert of the group is acknowledged")
    first_started_at: dt.datetime
    last_started_at: dt.datetime
    max_value: float | None
    message: str = Field(description="the latest alert's message")
    alert_ids: list[int] = Field(description="the group's latest alert ids (at most 100)")


class AlertGroupList(Out):
    items: list[AlertGroup]
    total: int


class AckGroupIn(In):
    """One group: the machine's alerts of ``kind`` on ``job_id`` (null: without a job)."""

    machine_id: int
    kind: str
    job_id: int | None = None


class AckGroupOut(Out):
    acknowledged: int
    ids: list[int]


class PointPage(Out):
    """Telemetry points (GeoJSON Point Features, time order), one page."""

    type: Literal["FeatureCollection"] = "FeatureCollection"
    features: list[Feature]
    machine_id: int | None = None
    total: int
    limit: int
    offset: int
    next_offset: int | None = Field(description="offset of the next page; null on the last")


class TrackDay(Out):
    """One local calendar day on which the machine recorded positions."""

    day: dt.date = Field(description="the day in the requested time zone")
    points: int = Field(description="records with a position that day")
    first_t: dt.datetime
    last_t: dt.datetime
    start: dt.datetime = Field(description="the day's start (pass as ``from`` to the track)")
    end: dt.datetime = Field(
        description="the day's last microsecond (pass as ``to``: the track's ``to`` is inclusive)"
    )


class TrackDays(Out):
    """Days with a track, newest first (route history by day)."""

    machine_id: int
    tz: str
    items: list[TrackDay]


class ChartOut(Out):
    """Column arrays, one value per record (``t`` in Unix seconds)."""

    machine_id: int
    n: int
    seq: list[int]
    t: list[float]
    speed_raw_m_s: list[float | None]
    speed_filtered_m_s: list[float | None]
    target_shaft_rpm: list[float | None]
    actual_shaft_rpm: list[float | None]
    target_rate_kg_ha: list[float | None]
    applied_rate_kg_ha: list[float | None]
    duty: list[float | None]
    fix_quality: list[int | None]
    cell_seq: list[int | None]
