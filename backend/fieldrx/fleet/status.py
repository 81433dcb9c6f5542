"""Machine status for the fleet view: online from the heartbeat timeout, position, job, rates.

The status describes the present (machines stayed "alarm" with their
last speed for tens of minutes after their simulations ended):

* a machine silent for longer than the heartbeat timeout (``FIELDRX_HEARTBEAT_TIMEOUT_S``)
  is ``offline``: no speed, no rates, no record alarms (they describe a moment long gone;
  ``last_speed_m_s`` keeps the last value for reference);
* ``sweep_offline`` announces that change on the live socket once (``machine_status.
  offline_at``) and ends the record-driven alerts the silent machine left open (their
  condition can no longer be observed); it runs in the worker loop and, while browsers
  are connected, in every API process (``fleet.live``). No GET writes for it.
* ``state`` is offline | alarm (an alert is active now) | working | moving | idle.
"""

from __future__ import annotations

import json
from typing import Any

import psycopg
from sqlalchemy import text
from sqlalchemy.orm import Session

from fieldrx.fleet.alerts import LIVE_CHANNEL, RECORD_KINDS, alert_message

MOVING_M_S = 0.3  # below this a machine stands (GNSS speed noise)

STATUS_SQL = text(
    """
    SELECT m.id AS machine_id, m.name, m.speed_min_m_s, m.speed_max_m_s,
           s.last_seen_at, s.last_t, s.acked_seq, s.lon, s.lat, s.speed_m_s, s.heading_deg,
           s.job_id AS record_job_id, s.cell_seq, s.target_rate_kg_ha, s.applied_rate_kg_ha,
           s.queue_backlog, s.alarms,
           coalesce(s.last_seen_at >= now() - make_interval(secs => :timeout), false) AS online,
           extract(epoch FROM now() - s.last_seen_at)::float8 AS silent_s,
           j.id AS job_id, j.name AS job_name, j.state AS job_state, j.cells_applied, j.n_cells,
           (SELECT count(*) FROM alerts a WHERE a.machine_id = m.id AND a.ended_at IS NULL)
               AS active_alerts
    FROM machines m
    LEFT JOIN machine_status s ON s.machine_id = m.id
    LEFT JOIN LATERAL (
        SELECT * FROM jobs WHERE jobs.machine_id = m.id
          AND jobs.state IN ('running', 'paused', 'downloaded', 'sent')
        ORDER BY (jobs.id = s.job_id) DESC, (jobs.state = 'running') DESC, jobs.updated_at DESC
        LIMIT 1
    ) j ON true
    WHERE m.organisation_id = :org AND (CAST(:mid AS int) IS NULL OR m.id = :mid)
    ORDER BY m.id
    """
)


def machine_status(
    session: Session, organisation_id: int, timeout_s: float, machine_id: int | None = None
) -> list[dict[str, Any]]:
    rows = session.execute(
        STATUS_SQL, {"org": organisation_id, "timeout": timeout_s, "mid": machine_id}
    ).mappings()
    out = []
    for r in rows:
        n = r["n_cells"] or 0
        online = bool(r["online"])
        tr, ar = r["target_rate_kg_ha"], r["applied_rate_kg_ha"]
        if not online:  # the last record's speed, rates and flags are history, not status
            tr = ar = None
        speed = r["speed_m_s"] if online else None
        state = present_state(online, r["active_alerts"] or 0, speed, r["job_state"])
        out.append(
            {
                "machine_id": r["machine_id"],
                "name": r["name"],
                "online": online,
                "state": state,
                "last_seen_at": r["last_seen_at"],
                "silent_s": r["silent_s"],
                "last_t": r["last_t"],
                "acked_seq": r["acked_seq"] or 0,
                "position": None
                if r["lon"] is None
                else {"type": "Point", "coordinates": [r["lon"], r["lat"]]},
                "speed_m_s": speed,
                "last_speed_m_s": r["speed_m_s"],
                "heading_deg": r["heading_deg"],
                "speed_range_m_s": [r["speed_min_m_s"], r["speed_max_m_s"]],
                "job": None
                if r["job_id"] is None
                else {
                    "id": r["job_id"],
                    "name": r["job_name"],
                    "state": r["job_state"],
                    "cells_applied": r["cells_applied"],
                    "n_cells": n,
                    "progress": (r["cells_applied"] / n) if n else 0.0,
                },
                "cell_seq": r["cell_seq"],
                "target_rate_kg_ha": tr,
                "applied_rate_kg_ha": ar,
                "rate_error_pct": (100.0 * (ar - tr) / tr) if (tr and ar is not None) else None,
                "queue_backlog": r["queue_backlog"] or 0,
                "alarms": list(r["alarms"] or []) if online else [],
                "active_alerts": r["active_alerts"],
            }
        )
    return out


def present_state(
    online: bool, active_alerts: int, speed_m_s: float | None, job_state: str | None
) -> str:
    """Offline beats everything (a silent machine's alarms are stale), then active alerts."""
    if not online:
        return "offline"
    if active_alerts > 0:
        return "alarm"
    moving = (speed_m_s or 0.0) > MOVING_M_S
    if moving and job_state == "running":
        return "working"
    return "moving" if moving else "idle"


# the database's time is read first and bound: past one node (Citus) ``now()`` is refused
# in the RETURNING list of a distributed table's UPDATE
SWEEP_SQL = """
UPDATE machine_status s SET offline_at = %(now)s
FROM machines m
WHERE m.id = s.machine_id
  AND s.last_seen_at < %(now)s - make_interval(secs => %(timeout)s)
  AND (s.offline_at IS NULL OR s.offline_at < s.last_seen_at)
RETURNING s.machine_id, m.organisation_id, s.last_seen_at,
          extract(epoch FROM %(now)s - s.last_seen_at)::float8
"""

END_STALE_SQL = """
UPDATE alerts a SET ended_at = greatest(a.started_at, ms.last_seen_at)
FROM machine_status ms
WHERE ms.machine_id = a.machine_id AND a.machine_id = ANY(%s)
  AND a.ended_at IS NULL AND a.kind = ANY(%s)
RETURNING a.id, a.organisation_id, a.machine_id, a.kind, a.job_id
"""


def sweep_offline(conn: psycopg.Connection[Any], timeout_s: float) -> list[int]:
    """Announce machines silent beyond ``timeout_s`` as offline (once per silence).

    Safe from many processes at once: the UPDATE's row locks let one sweep claim a
    machine and the others' re-checked WHERE skip it. Returns the machine ids announced.
    """
    with conn.transaction(), conn.cursor() as cur:
        cur.execute("SELECT now()")
        now = cur.fetchone()[0]  # type: ignore[index]
        cur.execute(SWEEP_SQL, {"now": now, "timeout": timeout_s})
        gone = cur.fetchall()
        if not gone:
            return []
        ids = [g[0] for g in gone]
        cur.execute(END_STALE_SQL, (ids, list(RECORD_KINDS)))
        ended = cur.fetchall()
        msgs = [
            alert_message(org, aid, mid, kind, "ended", job_id=jid)
            for aid, org, mid, kind, jid in ended
        ]
        msgs += [
            {
                "type": "machine",
                "event": "offline",
                "org": org,
                "machine_id": mid,
                "online": False,
                "state": "offline",
                "last_seen_at": seen.isoformat() if seen is not None else None,
                "silent_s": silent,
            }
            for mid, org, seen, silent in gone
        ]
        cur.execute(
            "SELECT pg_notify(%s, m) FROM unnest(%s::text[]) AS m",
            (LIVE_CHANNEL, [json.dumps(m, default=str) for m in msgs]),
        )
    return ids
