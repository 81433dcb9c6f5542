"""Ingest stage 6a, status: the machine's latest state after a batch (``machine_status``)."""

from __future__ import annotations

import datetime as dt
from typing import Any

from fieldrx.fleet.ingest.model import MachineInfo
from fieldrx.fleet.ingest.validate import FUTURE_TOLERANCE_S
from fieldrx.fleet.telemetry_row import TelemetryRow


def status_upsert(
    machine_id: int, info: MachineInfo, new: list[TelemetryRow], acked: int, now: float
) -> tuple[str, tuple[Any, ...]]:
    """The upsert of the machine's latest state (statement, parameters); position fields
    only move forward in record time (a stored latest time beyond the future tolerance is
    a clock error, not a reason to freeze the machine's state: newer real records replace
    it)."""
    if not new:
        return (
            "INSERT INTO machine_status (machine_id, last_seen_at, acked_seq, queue_backlog,"
            " alarms) VALUES (%s, now(), %s, 0, '{}') ON CONFLICT (machine_id) DO UPDATE"
            " SET last_seen_at = excluded.last_seen_at, acked_seq = excluded.acked_seq",
            (machine_id, acked),
        )
    r = max(new, key=lambda r: r.t)
    t = r.t_s
    if info.last_t is not None and t < info.last_t <= now + FUTURE_TOLERANCE_S:
        return (
            "UPDATE machine_status SET last_seen_at = now(), acked_seq = %s WHERE machine_id = %s",
            (acked, machine_id),
        )
    lon, lat = r.lonlat
    return (
        """
        INSERT INTO machine_status (machine_id, last_seen_at, last_t, acked_seq, lon, lat,
            speed_m_s, heading_deg, job_id, cell_seq, target_rate_kg_ha, applied_rate_kg_ha,
            queue_backlog, alarms)
        VALUES (%s, now(), %s, %s, %s, %s, %s, %s, %s, %s, %s, %s, %s, %s)
        ON CONFLICT (machine_id) DO UPDATE SET last_seen_at = excluded.last_seen_at,
            last_t = excluded.last_t,
            acked_seq = excluded.acked_seq,
            lon = coalesce(excluded.lon, machine_status.lon),
            lat = coalesce(excluded.lat, machine_status.lat),
            speed_m_s = excluded.speed_m_s, heading_deg = excluded.heading_deg,
            job_id = excluded.job_id, cell_seq = excluded.cell_seq,
            target_rate_kg_ha = excluded.target_rate_kg_ha,
            applied_rate_kg_ha = excluded.applied_rate_kg_ha,
            queue_backlog = excluded.queue_backlog, alarms = excluded.alarms
        """,
        (
            machine_id,
            dt.datetime.fromtimestamp(t, dt.UTC),
            acked,
            lon,
            lat,
            r.speed_m_s,
            r.heading_deg,
            r.job_id,
            r.cell_seq,
            r.target_rate_kg_ha,
            r.applied_rate_kg_ha,
            r.queue_backlog,
            r.alarms,
        ),
    )
