"""Fleet view: machine status, alerts (list, acknowledge), track replay and telemetry charts.

Mounted after the machines router; ``/machines/status`` is not shadowed because
the machine item routes use an ``int`` path converter.
"""

from __future__ import annotations

import datetime as dt
import json
import zoneinfo
from typing import Any

from fastapi import APIRouter, Query
from fastapi.responses import Response
from sqlalchemy import func, select, text, update

from fieldrx.api.common import ApiError, get_scoped, point_page
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.fleet import (
    AckGroupIn,
    AckGroupOut,
    AlertGroupList,
    AlertList,
    AlertOut,
    ChartOut,
    FleetStatusOut,
    PointPage,
    TrackDays,
)
from fieldrx.auth.deps import SessionDep, UserDep, WriterDep
from fieldrx.db.models import Alert, Machine
from fieldrx.fleet.alerts import ALERT_KINDS, LIVE_CHANNEL, check_no_data
from fieldrx.fleet.db import raw_connection
from fieldrx.fleet.partitions import machine_window
from fieldrx.fleet.status import machine_status
from fieldrx.settings import get_settings

router = APIRouter(tags=["fleet"], responses=ERRORS)


@router.get("/machines/status", response_model=FleetStatusOut)
def fleet_status(principal: UserDep, session: SessionDep) -> dict[str, Any]:
    """Every machine of the organisation: online (heartbeat), position, job, rates, backlog."""
    timeout = get_settings().heartbeat_timeout_s
    with raw_connection() as conn:
        check_no_data(conn, timeout, wait=False)  # never queue a read behind a sweep
    return {
        "heartbeat_timeout_s": timeout,
        "server_time": dt.datetime.now(dt.UTC),
        "items": machine_status(session, principal.organisation_id, timeout),
    }


def _alert_out(a: Alert) -> dict[str, Any]:
    return {
        "id": a.id,
        "machine_id": a.machine_id,
        "job_id": a.job_id,
        "kind": a.kind,
        "message": a.message,
        "value": a.value,
        "started_at": a.started_at,
        "ended_at": a.ended_at,
        "active": a.ended_at is None,
        "acknowledged_at": a.acknowledged_at,
        "acknowledged_by": a.acknowledged_by,
    }


@router.get("/alerts", response_model=AlertList)
def list_alerts(
    principal: UserDep,
    session: SessionDep,
    active: bool | None = Query(default=None, description="true: not ended; false: ended"),
    acknowledged: bool | None = None,
    machine_id: int | None = None,
    job_id: int | None = None,
    kind: str | None = Query(default=None, description=" | ".join(ALERT_KINDS)),
    limit: int = Query(default=100, ge=1, le=1000),
    offset: int = Query(default=0, ge=0),
) -> dict[str, Any]:
    with raw_connection() as conn:
        check_no_data(conn, get_settings().heartbeat_timeout_s, wait=False)
    stmt = select(Alert).where(Alert.organisation_id == principal.organisation_id)
    if active is not None:
        stmt = stmt.where(Alert.ended_at.is_(None) if active else Alert.ended_at.is_not(None))
    if acknowledged is not None:
        stmt = stmt.where(
            Alert.acknowledged_at.is_not(None) if acknowledged else Alert.acknowledged_at.is_(None)
        )
    if machine_id is not None:
        stmt = stmt.where(Alert.machine_id == machine_id)
    if job_id is not None:
        stmt = stmt.where(Alert.job_id == job_id)
    if kind is not None:
        if kind not in ALERT_KINDS:
            raise ApiError(422, f"unknown alert kind '{kind}'", where="kind", allowed=ALERT_KINDS)
        stmt = stmt.where(Alert.kind == kind)
    total = session.scalar(select(func.count()).select_from(stmt.subquery())) or 0
    rows = session.scalars(
        stmt.order_by(Alert.started_at.desc(), Alert.id.desc()).limit(limit).offset(offset)
    )
    return {"items": [_alert_out(a) for a in rows], "total": total}


@router.post("/alerts/{alert_id:int}/ack", response_model=AlertOut)
def ack_alert(alert_id: int, principal: WriterDep, session: SessionDep) -> dict[str, Any]:
    """Acknowledge: someone has seen it. An active alert stays active until its cause ends."""
    a = get_scoped(session, Alert, alert_id, principal)
    if a.acknowledged_at is None:
        a.acknowledged_at = dt.datetime.now(dt.UTC)
        a.acknowledged_by = principal.user_id
        session.commit()
    return _alert_out(a)


GROUPS_SQL = """
SELECT machine_id, job_id, kind, count(*) AS count,
       count(*) FILTER (WHERE ended_at IS NULL) AS active,
       count(*) FILTER (WHERE acknowledged_at IS NULL) AS unacknowledged,
       min(started_at) AS first_started_at, max(started_at) AS last_started_at,
       max(value) AS max_value,
       (array_agg(message ORDER BY started_at DESC, id DESC))[1] AS message,
       (array_agg(id ORDER BY started_at DESC, id DESC))[1:100] AS alert_ids
FROM alerts
WHERE organisation_id = :org
  AND (CAST(:mid AS int) IS NULL OR machine_id = :mid)
  AND (CAST(:jid AS int) IS NULL OR job_id = :jid)
GROUP BY machine_id, job_id, kind
HAVING (CAST(:active AS boolean) IS NULL
        OR (count(*) FILTER (WHERE ended_at IS NULL) > 0) = :active)
   AND (CAST(:acked AS boolean) IS NULL
        OR (count(*) FILTER (WHERE acknowledged_at IS NULL) = 0) = :acked)
ORDER BY max(started_at) DESC, machine_id, kind
LIMIT :lim
"""


@router.get("/alerts/groups", response_model=AlertGroupList)
def alert_groups(
    principal: UserDep,
    session: SessionDep,
    active: bool | None = Query(default=None, description="true: some alert not ended"),
    acknowledged: bool | None = Query(default=None, description="false: some not acknowledged"),
    machine_id: int | None = None,
    job_id: int | None = None,
    limit: int = Query(default=100, ge=1, le=1000),
) -> dict[str, Any]:
    """Alerts of one kind on one job (machine and kind without a job) as one group: a job
    whose rate wandered in and out of tolerance 16 times is one line, acknowledged at once."""
    rows = session.execute(
        text(GROUPS_SQL),
        {
            "org": principal.organisation_id,
            "mid": machine_id,
            "jid": job_id,
            "active": active,
            "acked": acknowledged,
            "lim": limit,
        },
    ).mappings()
    items = [
        {
            **dict(r),
            "alert_ids": list(r["alert_ids"] or []),
            "acknowledged": r["unacknowledged"] == 0,
        }
        for r in rows
    ]
    return {"items": items, "total": len(items)}


@router.post("/alerts/ack", response_model=AckGroupOut)
def ack_alert_group(body: AckGroupIn, principal: WriterDep, session: SessionDep) -> dict[str, Any]:
    """Acknowledge every alert of a group at once (ended or active; active ones stay active)."""
    if body.kind not in ALERT_KINDS:
        raise ApiError(422, f"unknown alert kind '{body.kind}'", where="kind", allowed=ALERT_KINDS)
    get_scoped(session, Machine, body.machine_id, principal)
    job_cond = Alert.job_id.is_(None) if body.job_id is None else Alert.job_id == body.job_id
    now = dt.datetime.now(dt.UTC)
    ids = session.scalars(
        update(Alert)
        .where(
            Alert.organisation_id == principal.organisation_id,
            Alert.machine_id == body.machine_id,
            Alert.kind == body.kind,
            job_cond,
            Alert.acknowledged_at.is_(None),
        )
        .values(acknowledged_at=now, acknowledged_by=principal.user_id)
        .returning(Alert.id)
    ).all()
    msg = {
        "type": "alert",
        "event": "acknowledged",
        "org": principal.organisation_id,
        "machine_id": body.machine_id,
        "job_id": body.job_id,
        "kind": body.kind,
        "ids": list(ids),
    }
    session.execute(text("SELECT pg_notify(:c, :p)"), {"c": LIVE_CHANNEL, "p": json.dumps(msg)})
    session.commit()
    return {"acknowledged": len(ids), "ids": list(ids)}


def _range(
    frm: dt.datetime | None, to: dt.datetime | None
) -> tuple[dt.datetime | None, dt.datetime | None]:
    if frm is not None and to is not None and to < frm:
        raise ApiError(422, "'to' is before 'from'", where="to")
    return frm, to


# a machine's track and chart rows: the machine, and a time range (fleet.partitions
# .machine_window) that names the days read
TRACK_WHERE = "machine_id = :m AND geom IS NOT NULL AND t BETWEEN :t0 AND :t1"
CHART_WHERE = "machine_id = :m AND t BETWEEN :t0 AND :t1"


def window_headers(window: dict[str, Any]) -> dict[str, str]:
    """The time range a track or chart answer covers, as ``X-FieldRx-From`` /
    ``X-FieldRx-To`` (ISO 8601): a request without a range gets the machine's latest day,
    and says so, rather than silently answering less than "everything" (empty: no records)."""
    return {
        "X-FieldRx-From": window["t0"].isoformat() if window["t0"] else "",
        "X-FieldRx-To": window["t1"].isoformat() if window["t1"] else "",
    }


@router.get("/machines/{machine_id:int}/track", response_model=PointPage)
def machine_track(
    machine_id: int,
    principal: UserDep,
    session: SessionDep,
    frm: dt.datetime | None = Query(default=None, alias="from"),
    to: dt.datetime | None = None,
    limit: int = Query(default=1000, ge=1, le=10000),
    offset: int = Query(default=0, ge=0),
) -> Response:
    """History replay: the machine's positions in time order, one page at a time (GeoJSON).

    Without ``from``/``to``: the machine's latest day of records. The range answered is in
    the ``X-FieldRx-From`` / ``X-FieldRx-To`` headers; ``/track/days`` lists every day.
    """
    get_scoped(session, Machine, machine_id, principal)
    frm, to = _range(frm, to)
    # bounded in time (no range: the machine's latest day), so only those days are read
    window = machine_window(session, machine_id, frm, to)
    params = {**window, "m": machine_id, "lim": limit, "off": offset}
    total = session.execute(
        text(f"SELECT count(*) FROM telemetry WHERE {TRACK_WHERE}"), params
    ).scalar_one()
    rows = session.execute(
        text(
            f"SELECT seq, t, ST_X(geom) AS lon, ST_Y(geom) AS lat, fix_quality, hdop,"
            f" speed_raw_m_s, speed_filtered_m_s, heading_deg, job_id, cell_seq,"
            f" target_rate_kg_ha, applied_rate_kg_ha, target_shaft_rpm, actual_shaft_rpm,"
            f" duty, implement_down, alarms FROM telemetry WHERE {TRACK_WHERE}"
            f" ORDER BY t, seq LIMIT :lim OFFSET :off"
        ),
        params,
    )
    page = point_page(rows, total or 0, limit, offset, machine_id=machine_id)
    page.headers.update(window_headers(window))
    return page


DAYS_SQL = """
SELECT (t AT TIME ZONE :tz)::date AS day, count(*) AS points, min(t) AS first_t, max(t) AS last_t
FROM telemetry WHERE machine_id = :m AND geom IS NOT NULL
GROUP BY 1 ORDER BY 1 DESC LIMIT :lim
"""


MICROSECOND = dt.timedelta(microseconds=1)


def _zone(tz: str) -> zoneinfo.ZoneInfo:
    try:
        return zoneinfo.ZoneInfo(tz)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        raise ApiError(
            422, f"unknown time zone '{tz}' (an IANA name such as 'Europe/Berlin')", where="tz"
        ) from None


@router.get("/machines/{machine_id:int}/track/days", response_model=TrackDays)
def machine_track_days(
    machine_id: int,
    principal: UserDep,
    session: SessionDep,
    tz: str = Query(default="UTC", description="IANA time zone the days are counted in"),
    limit: int = Query(default=366, ge=1, le=3660),
) -> dict[str, Any]:
    """The days on which the machine has a track, newest first, each with its bounds in
    ``tz``: the UI's route history asks ``/track?from=start&to=end`` for the chosen day
    (a farm's day is local: a night shift after 00:00 UTC is still "today" in Europe)."""
    get_scoped(session, Machine, machine_id, principal)
    zone = _zone(tz)
    rows = session.execute(text(DAYS_SQL), {"m": machine_id, "tz": tz, "lim": limit}).all()
    items = []
    for day, points, first_t, last_t in rows:
        start = dt.datetime.combine(day, dt.time(), zone)
        # ``to`` is inclusive: the day's last microsecond (timestamptz's resolution), so a
        # record at the next midnight is not on both days
        end = dt.datetime.combine(day + dt.timedelta(days=1), dt.time(), zone) - MICROSECOND
        items.append(
            {
                "day": day,
                "points": points,
                "first_t": first_t,
                "last_t": last_t,
                "start": start,
                "end": end,
            }
        )
    return {"machine_id": machine_id, "tz": tz, "items": items}


CHART_COLUMNS = (
    "speed_raw_m_s",
    "speed_filtered_m_s",
    "target_shaft_rpm",
    "actual_shaft_rpm",
    "target_rate_kg_ha",
    "applied_rate_kg_ha",
    "duty",
    "fix_quality",
    "cell_seq",
)


@router.get("/machines/{machine_id:int}/telemetry", response_model=ChartOut)
def machine_telemetry(
    machine_id: int,
    principal: UserDep,
    session: SessionDep,
    response: Response,
    frm: dt.datetime | None = Query(default=None, alias="from"),
    to: dt.datetime | None = None,
    limit: int = Query(default=5000, ge=1, le=50000),
) -> dict[str, Any]:
    """Column arrays for charts (raw vs filtered speed, target vs actual shaft speed, rates).

    Without a range: the latest ``limit`` records of the machine's latest day; with one: the
    first ``limit`` in it. The range answered is in ``X-FieldRx-From`` / ``X-FieldRx-To``.
    """
    get_scoped(session, Machine, machine_id, principal)
    frm, to = _range(frm, to)
    cols = ", ".join(CHART_COLUMNS)
    latest = frm is None and to is None
    sql = (
        f"SELECT seq, extract(epoch FROM t)::float8 AS t, {cols} FROM telemetry"
        f" WHERE {CHART_WHERE} ORDER BY t {'DESC' if latest else 'ASC'}, seq LIMIT :lim"
    )
    window = machine_window(session, machine_id, frm, to)
    rows = session.execute(text(sql), {**window, "m": machine_id, "lim": limit}).all()
    response.headers.update(window_headers(window))
    if latest:
        rows = rows[::-1]
    keys = ("seq", "t", *CHART_COLUMNS)
    out: dict[str, Any] = {"machine_id": machine_id, "n": len(rows)}
    for i, k in enumerate(keys):
        out[k] = [r[i] for r in rows]
    return out
