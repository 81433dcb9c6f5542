"""Ingest stage 7, live: the messages a batch sends to the fleet view.

The stages return their messages (position, job progress, alerts); the batch's
transaction queues them all with one NOTIFY (``fleet.alerts.notify``), delivered at its
commit to every API process listening (``fleet.live``).
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from typing import Any

from fieldrx.fleet.ingest.model import IngestResult
from fieldrx.fleet.telemetry_row import TelemetryRow


def position_message(org: int, r: TelemetryRow, result: IngestResult) -> dict[str, Any]:
    """The machine's latest record of the batch, with the batch's ack."""
    lon, lat = r.lonlat
    return {
        "type": "position",
        "org": org,
        "machine_id": r.machine_id,
        "seq": r.seq,
        "t": r.t_s,
        "lon": lon,
        "lat": lat,
        "fix_quality": r.fix_quality,
        "speed_m_s": r.speed_m_s,
        "heading_deg": r.heading_deg,
        "job_id": r.job_id,
        "cell_seq": r.cell_seq,
        "target_rate_kg_ha": r.target_rate_kg_ha,
        "applied_rate_kg_ha": r.applied_rate_kg_ha,
        "ndvi": r.ndvi,  # sensor jobs: the fleet view shows the kind's own figure
        "depth_mm": r.depth_mm,
        "implement_down": r.implement_down,
        "alarms": r.alarms,
        "queue_backlog": r.queue_backlog,
        "acked_seq": result.acked_seq,
        "stored": result.stored,
        "sent_at": time.time(),
    }


def job_messages(machine_id: int, org: int, moved: Iterable[Any]) -> list[dict[str, Any]]:
    """Live messages of the jobs whose progress moved (``progress.CELL_PROGRESS_CTE``'s
    ``moved``: id, state, cells_applied, n_cells)."""
    return [
        {
            "type": "job",
            "org": org,
            "job_id": jid,
            "machine_id": machine_id,
            "state": state,
            "cells_applied": applied,
            "n_cells": n,
            "progress": (applied / n) if n else 0.0,
        }
        for jid, state, applied, n in moved
    ]
