"""Machine status for the fleet view: online from the heartbeat timeout, position, job, rates."""

from __future__ import annotations

from typing import Any

from sqlalchemy import text
from sqlalchemy.orm import Session

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
        tr, ar = r["target_rate_kg_ha"], r["applied_rate_kg_ha"]
        out.append(
            {
                "machine_id": r["machine_id"],
                "name": r["name"],
                "online": bool(r["online"]),
                "last_seen_at": r["last_seen_at"],
                "silent_s": r["silent_s"],
                "last_t": r["last_t"],
                "acked_seq": r["acked_seq"] or 0,
                "position": None
                if r["lon"] is None
                else {"type": "Point", "coordinates": [r["lon"], r["lat"]]},
                "speed_m_s": r["speed_m_s"],
                "speed_kmh": None if r["speed_m_s"] is None else r["speed_m_s"] * 3.6,
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
                "alarms": list(r["alarms"] or []),
                "active_alerts": r["active_alerts"],
            }
        )
    return out
