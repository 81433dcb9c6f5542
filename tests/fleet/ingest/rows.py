"""Typed rows and machine states for the stage tests (no database)."""

from __future__ import annotations

from typing import Any

from fieldrx.fleet.ingest.model import MachineInfo
from fieldrx.fleet.ingest.validate import validate
from fieldrx.fleet.telemetry_row import TelemetryRow
from fieldrx_edge.protocol import TELEMETRY_FIELDS

NOW = 1_790_000_000.0
M = 7


def rows(*seqs: int, **kw: Any) -> list[TelemetryRow]:
    """Valid rows of machine ``M`` at 10 Hz before ``NOW``, fields overridden by ``kw``."""
    recs = []
    for q in seqs:
        r: dict[str, Any] = {f: None for f in TELEMETRY_FIELDS}
        r.update(machine_id=M, seq=q, t=NOW - 100.0 + q * 0.1, lon=11.0, lat=48.0,
                 fix_quality=4, speed_filtered_m_s=2.0, job_id=3, cell_seq=q // 10,
                 target_rate_kg_ha=100.0, applied_rate_kg_ha=100.0, implement_down=True,
                 alarms=[], queue_backlog=0)  # fmt: skip
        r.update(kw)
        recs.append(r)
    valid, rejected, _, _ = validate(recs, M, "s", NOW)
    assert not rejected, rejected
    return list(valid.values())


def info(**kw: Any) -> MachineInfo:
    """A machine of organisation 1 planned for 1-3 m/s, nothing open, stream ``kw``."""
    base: dict[str, Any] = dict(
        organisation_id=1, speed_min_m_s=1.0, speed_max_m_s=3.0, acked_seq=None, last_t=None,
        open_alerts={}, stream_seen=None, other_seen=None,
    )  # fmt: skip
    base.update(kw)
    return MachineInfo(**base)
