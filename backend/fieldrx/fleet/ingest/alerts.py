"""Ingest stage 6b, alerts: what a batch opens or ends, in its transaction.

Two events ingest raises itself (``fleet.alerts.EVENT_KINDS``): ``far_past_records`` and
``duplicate_stream`` (two streams sending at once for one machine: both are kept). Then
the record rules (``fleet.alerts.evaluate``) when the batch could change any, and the
seeding jobs' depth window (``fleet.seed_alerts``) when it carries depths.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

import psycopg

from fieldrx.fleet import alerts as alert_rules
from fieldrx.fleet.ingest.model import MachineInfo
from fieldrx.fleet.partitions import ON_DEMAND_DAYS, is_far_past
from fieldrx.fleet.seed_alerts import check_depth_window
from fieldrx.fleet.telemetry_row import TelemetryRow

CONCURRENT_WINDOW_S = 60.0  # two streams both sending within this: a duplicate_stream alert


def far_past_alert(
    cur: psycopg.Cursor[Any], machine_id: int, info: MachineInfo, new: list[TelemetryRow]
) -> list[dict[str, Any]]:
    """``far_past_records``: the machine stored records dated more than ``ON_DEMAND_DAYS``
    ago (a device clock reset to 2000, say). They are kept in the default partition, not
    in a day of their own; the fleet manager sees why their track is not where expected."""
    far = [r for r in new if is_far_past(r.t)]
    if not far or "far_past_records" in info.event_alerts:
        return []
    first = min(far, key=lambda r: r.t)
    return alert_rules.open_event(
        cur, info.organisation_id, machine_id, first.job_id, "far_past_records",
        f"{len(far)} record(s) dated from {_iso(first.t_s)} are more than"
        f" {ON_DEMAND_DAYS} days old (device clock?): stored in the default partition",
        None,
    )  # fmt: skip


def _iso(t_s: float) -> str:
    return dt.datetime.fromtimestamp(t_s, dt.UTC).strftime("%Y-%m-%d %H:%M:%SZ")


def streams_alert(
    cur: psycopg.Cursor[Any],
    machine_id: int,
    info: MachineInfo,
    new: list[TelemetryRow],
    now: float,
) -> list[dict[str, Any]]:
    """``duplicate_stream``: another stream of this machine sent a batch since this stream's
    previous one, within ``CONCURRENT_WINDOW_S`` (two agents, e.g. two tablets with one
    device token). A queue replaced by a new one never sends again, so a sequential restart
    does not alert. Ended once only this stream has been sending for the window."""
    other, mine = info.other_seen, info.stream_seen
    kind = "duplicate_stream"
    recent = other is not None and now - other < CONCURRENT_WINDOW_S
    if recent and mine is not None and other is not None and other > mine:
        if kind in info.event_alerts:
            return []
        return alert_rules.open_event(
            cur, info.organisation_id, machine_id, new[-1].job_id if new else None, kind,
            "two telemetry streams are sending for this machine at once (two agents with one"
            " device token?); both are stored",
            None,
        )  # fmt: skip
    if kind in info.event_alerts and not recent:
        return alert_rules.end_event(
            cur, info.organisation_id, machine_id, info.event_alerts[kind], kind
        )
    return []


def may_alert(new: list[TelemetryRow], info: MachineInfo) -> bool:
    """Cheap pre-check: could any alert open or close with this batch? (Most batches: no.)"""
    if info.open_alerts:
        return True
    lo, hi = info.speed_min_m_s, info.speed_max_m_s
    tol = alert_rules.RULES.rate_tolerance
    for r in new:
        if r.fix_quality == 0 or r.alarms:  # no fix, or any alarm from the agent
            return True
        if r.implement_down:
            v = r.speed_m_s
            if v is not None and (v < lo or v > hi):
                return True
            tr, ar = r.target_rate_kg_ha, r.applied_rate_kg_ha
            if tr is not None and ar is not None and tr > 0 and abs(ar - tr) > tol * tr:
                return True
    return False


def record_alerts(
    cur: psycopg.Cursor[Any], machine_id: int, info: MachineInfo, new: list[TelemetryRow]
) -> list[dict[str, Any]]:
    """The record rules over the batch's new rows (time-ordered), then a seeding job's
    depth window; both name the job of the batch's latest record."""
    latest = max(new, key=lambda r: r.t)
    messages: list[dict[str, Any]] = []
    if may_alert(new, info):
        samples = [
            alert_rules.Sample(
                r.t_s,
                r.fix_quality,
                r.speed_m_s,
                r.target_rate_kg_ha,
                r.applied_rate_kg_ha,
                r.implement_down,
                r.alarms,
            )
            for r in sorted(new, key=lambda r: r.t)
        ]
        scope = alert_rules.Scope(
            machine_id, info.organisation_id, latest.job_id, info.speed_min_m_s,
            info.speed_max_m_s, info.open_alerts,
        )  # fmt: skip
        messages.extend(alert_rules.evaluate(cur, scope, samples))
    if any(r.depth_mm is not None for r in new):  # seeding job
        messages.extend(
            check_depth_window(
                cur, machine_id, info.organisation_id, latest.job_id, info.open_alerts
            )
        )
    return messages
