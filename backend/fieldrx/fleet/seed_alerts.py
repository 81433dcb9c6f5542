"""Live alert of seeding jobs (seed 002): the qualified depth share over the last
``alert_window_m`` metres worked, checked as records arrive.

Called by ingest for batches that carry measured depths. The window is the job's own
setting (default 50 m) and so is the threshold (default 90 %); the share uses GB/T 20865's
band (``fieldrx_edge.depth.qualified_band_mm``) over the records of the trailing window,
distance from the filtered speed x time (``fieldrx_edge.jobkinds.figures``, the report's
definition). The alert opens when the share drops below the threshold with a full window
behind it, and ends when it is back at or above it.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

import psycopg
from fieldrx_edge.depth import qualified_band_mm

from fieldrx.fleet.alerts import alert_message
from fieldrx.jobkinds.registry import hooks

KIND = "depth_qualified_low"
MIN_SPEED_M_S = 0.25  # the slowest working speed the look-back must cover (0.9 km/h)


def check_depth_window(
    cur: psycopg.Cursor[Any],
    machine_id: int,
    organisation_id: int,
    job_id: int | None,
    open_ids: dict[str, int],
) -> list[dict[str, Any]]:
    """The live alerts of the job's kind (its server hook, ``fieldrx.jobkinds``); returns
    live messages."""
    if job_id is None:
        return []
    cur.execute(
        "SELECT kind, settings FROM jobs WHERE machine_id = %s AND id = %s", (machine_id, job_id)
    )
    row = cur.fetchone()
    live = hooks(row[0]).live_alerts if row is not None else None
    if row is None or live is None:
        return []
    return live(cur, machine_id, organisation_id, job_id, row[1], open_ids)


def depth_window(
    cur: psycopg.Cursor[Any],
    machine_id: int,
    organisation_id: int,
    job_id: int,
    s: dict[str, Any],
    open_ids: dict[str, int],
) -> list[dict[str, Any]]:
    """Open / close the seeding job's ``depth_qualified_low`` alert; returns live messages."""
    window_m = float(s["alert_window_m"])
    min_pct = float(s["alert_min_qualified_pct"])
    lo, hi = qualified_band_mm(float(s["target_depth_mm"]))
    # the job's latest record time: its span (fleet.partitions), widened by this batch
    cur.execute(
        "SELECT last_t FROM telemetry_job_spans WHERE machine_id = %s AND job_id = %s",
        (machine_id, job_id),
    )
    last = cur.fetchone()
    if last is None:
        return []
    cur.execute(
        "SELECT extract(epoch FROM t)::float8, speed_filtered_m_s, depth_mm FROM telemetry"
        " WHERE machine_id = %s AND job_id = %s AND implement_down AND depth_mm IS NOT NULL"
        " AND t BETWEEN %s AND %s ORDER BY t DESC",
        (
            machine_id,
            job_id,
            last[0] - dt.timedelta(seconds=window_m / MIN_SPEED_M_S + 2.0),
            last[0],
        ),
    )
    dist = 0.0
    n = ok = 0
    prev_t: float | None = None
    full = False
    for t, v, depth in cur.fetchall():
        if prev_t is not None:
            dist += (v or 0.0) * max(0.0, min(prev_t - t, 1.0))
        prev_t = t
        if dist > window_m:
            full = True
            break
        n += 1
        ok += lo <= depth <= hi
    if not full or n == 0:
        return []
    share = 100.0 * ok / n
    is_open = KIND in open_ids
    if share < min_pct and not is_open:
        text = (
            f"sowing depth qualified ({lo:g}-{hi:g} mm) {share:.1f} % over the last"
            f" {window_m:g} m, below {min_pct:g} %"
        )
        cur.execute(
            "INSERT INTO alerts (organisation_id, machine_id, job_id, kind, message, value,"
            " started_at) VALUES (%s, %s, %s, %s, %s, %s, now()) RETURNING id",
            (organisation_id, machine_id, job_id, KIND, text, share),
        )
        aid = cur.fetchone()[0]  # type: ignore[index]
        open_ids[KIND] = aid
        return [
            alert_message(organisation_id, aid, machine_id, KIND, "started", text, share, job_id)
        ]
    if share >= min_pct and is_open:
        cur.execute(
            "UPDATE alerts SET ended_at = now() WHERE machine_id = %s AND id = %s",
            (machine_id, open_ids[KIND]),
        )
        aid = open_ids.pop(KIND)
        return [alert_message(organisation_id, aid, machine_id, KIND, "ended")]
    return []
