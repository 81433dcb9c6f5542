"""What the operator did during a job, from the records' tags (``fieldrx_edge.cab``): where
and for how long the prescription was overridden (pause, rate override, a section off by
hand), and each acknowledgement of the cab's alarms with the alarms it acknowledged.

The agent tags every record written while an override is in force, so the time is the sum
of those records' fix periods (``fix_period_s``, the time each record stands for) and the
place is where the first and last of them were."""

from __future__ import annotations

import datetime as dt
from typing import Any

from sqlalchemy import text
from sqlalchemy.orm import Session

from fieldrx.fleet.partitions import job_window

OPERATOR_TAGS = ("operator_pause", "operator_rate_override", "operator_section_off")
ACK = "alarm_ack"

_OVERRIDES_SQL = text(
    "SELECT tag, count(*), coalesce(sum(fix_period_s), 0)::float8,"
    " extract(epoch FROM min(t))::float8, extract(epoch FROM max(t))::float8,"
    " (array_agg(ST_X(geom) ORDER BY t) FILTER (WHERE geom IS NOT NULL))[1],"
    " (array_agg(ST_Y(geom) ORDER BY t) FILTER (WHERE geom IS NOT NULL))[1],"
    " (array_agg(ST_X(geom) ORDER BY t DESC) FILTER (WHERE geom IS NOT NULL))[1],"
    " (array_agg(ST_Y(geom) ORDER BY t DESC) FILTER (WHERE geom IS NOT NULL))[1]"
    " FROM telemetry, unnest(alarms) AS tag"
    " WHERE machine_id = :m AND job_id = :j AND t BETWEEN :t0 AND :t1"
    " AND tag = ANY(CAST(:tags AS varchar[])) GROUP BY tag ORDER BY tag"
)
_ACKS_SQL = text(
    "SELECT extract(epoch FROM t)::float8, alarms, ST_X(geom), ST_Y(geom) FROM telemetry"
    " WHERE machine_id = :m AND job_id = :j AND t BETWEEN :t0 AND :t1"
    " AND :ack = ANY(alarms) ORDER BY t"
)


def _iso(t: float | None) -> str | None:
    return None if t is None else dt.datetime.fromtimestamp(t, dt.UTC).isoformat()


def operator_events(session: Session, machine_id: int, job_id: int) -> dict[str, Any]:
    """``{"overrides": [...], "alarm_acks": [...]}`` of the job (empty lists: none)."""
    params: dict[str, Any] = {
        "m": machine_id,
        "j": job_id,
        **job_window(session, machine_id, job_id),
    }
    overrides = [
        {
            "action": tag,
            "records": int(n),
            "seconds": round(float(secs), 3),
            "first_at": _iso(t0),
            "last_at": _iso(t1),
            "from_lon_lat": None if x0 is None else [x0, y0],
            "to_lon_lat": None if x1 is None else [x1, y1],
        }
        for tag, n, secs, t0, t1, x0, y0, x1, y1 in session.execute(
            _OVERRIDES_SQL, {**params, "tags": list(OPERATOR_TAGS)}
        )
    ]
    acks = [
        {
            "at": _iso(t),
            "alarms": sorted(a for a in alarms if a != ACK and a not in OPERATOR_TAGS),
            "lon_lat": None if x is None else [x, y],
        }
        for t, alarms, x, y in session.execute(_ACKS_SQL, {**params, "ack": ACK})
    ]
    return {"overrides": overrides, "alarm_acks": acks}
