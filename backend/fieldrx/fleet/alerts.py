"""Alert rules: conditions on telemetry records that must hold for a while before they alert.

An alert opens when its condition has held continuously for ``duration_s``
(record time), and closes (``ended_at``) at the first record where it no longer
holds. Users acknowledge alerts; acknowledging does not close them. ``no_data``
is the one alert without records: a machine running a job but silent beyond the
heartbeat timeout, checked on status queries and in the worker loop.
"""

from __future__ import annotations

import datetime as dt
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import psycopg

# events ingest opens and ends itself (not conditions on records, see fleet.ingest.alerts)
# duplicate_stream: two agent queues sending for one machine at once; far_past_records:
# records dated more than the partitions' on-demand bound ago, kept in the default partition
EVENT_KINDS = ("duplicate_stream", "far_past_records")
ALERT_KINDS = (
    "rate_error",
    "speed_out_of_range",
    "shaft_saturation",
    "fix_lost",
    "no_data",
    "cells_not_applied",
    "depth_qualified_low",  # seeding job: qualified depth share fell below the job's threshold
    *EVENT_KINDS,
)
LIVE_CHANNEL = "fieldrx_live"
# kinds opened and closed by records; a machine gone silent leaves them unobservable
RECORD_KINDS = ("rate_error", "speed_out_of_range", "shaft_saturation", "fix_lost")

SATURATION_ALARMS = frozenset({"shaft_above_range", "shaft_below_range", "motor_saturated"})


@dataclass(frozen=True)
class AlertRules:
    """Tolerances; durations are record time so a replayed backlog alerts like live data."""

    rate_tolerance: float = 0.10  # |applied - target| / target
    rate_duration_s: float = 5.0
    speed_duration_s: float = 3.0
    saturation_duration_s: float = 2.0
    fix_lost_duration_s: float = 2.0


RULES = AlertRules()


@dataclass(frozen=True)
class Sample:
    """The fields of a record the rules look at (from a new record or a stored row)."""

    t: float
    fix_quality: int
    speed_m_s: float | None
    target_rate_kg_ha: float | None
    applied_rate_kg_ha: float | None
    implement_down: bool
    alarms: Sequence[str]


Condition = Callable[[Sample], "float | None"]


def conditions(
    speed_min_m_s: float, speed_max_m_s: float, rules: AlertRules = RULES
) -> dict[str, tuple[float, Condition, str]]:
    """kind -> (duration_s, condition returning the offending value or None, message)."""

    def rate(s: Sample) -> float | None:
        tr, ar = s.target_rate_kg_ha, s.applied_rate_kg_ha
        if not s.implement_down or tr is None or ar is None or tr <= 0:
            return None
        err = abs(ar - tr) / tr
        return err * 100.0 if err > rules.rate_tolerance else None

    def speed(s: Sample) -> float | None:
        v = s.speed_m_s
        if not s.implement_down or v is None:
            return None
        return v if (v < speed_min_m_s or v > speed_max_m_s) else None

    def saturation(s: Sample) -> float | None:
        return 1.0 if SATURATION_ALARMS.intersection(s.alarms) else None

    def fix(s: Sample) -> float | None:
        return float(s.fix_quality) if (s.fix_quality == 0 or "fix_lost" in s.alarms) else None

    tol = rules.rate_tolerance * 100
    return {
        "rate_error": (
            rules.rate_duration_s,
            rate,
            f"applied rate off target by more than {tol:.0f} % for {rules.rate_duration_s:g} s",
        ),
        "speed_out_of_range": (
            rules.speed_duration_s,
            speed,
            f"ground speed outside the planned {speed_min_m_s * 3.6:.1f}-{speed_max_m_s * 3.6:.1f}"
            f" km/h for {rules.speed_duration_s:g} s",
        ),
        "shaft_saturation": (
            rules.saturation_duration_s,
            saturation,
            "metering shaft speed saturated (target beyond the calibrated range or motor at limit)",
        ),
        "fix_lost": (rules.fix_lost_duration_s, fix, "GNSS fix lost"),
    }


def _ts(t: float) -> dt.datetime:
    return dt.datetime.fromtimestamp(t, dt.UTC)


@dataclass(frozen=True)
class Scope:
    """Whose samples ``evaluate`` looks at: the machine, its organisation, the job its
    latest record names (a new alert's job), the job's planned speed range, and the
    machine's alerts not ended yet (kind -> id, read with the machine row under the ingest
    lock)."""

    machine_id: int
    organisation_id: int
    job_id: int | None
    speed_min_m_s: float
    speed_max_m_s: float
    open_ids: dict[str, int]


def evaluate(
    cur: psycopg.Cursor[Any], scope: Scope, samples: list[Sample], rules: AlertRules = RULES
) -> list[dict[str, Any]]:
    """Open/close alerts for a batch of new samples (time-ordered). Returns live messages."""
    if not samples:
        return []
    machine_id, organisation_id, job_id = scope.machine_id, scope.organisation_id, scope.job_id
    open_ids = dict(scope.open_ids)
    conds = conditions(scope.speed_min_m_s, scope.speed_max_m_s, rules)
    messages: list[dict[str, Any]] = []
    # data arrived: a no_data alert is over
    if "no_data" in open_ids:
        cur.execute(
            "UPDATE alerts SET ended_at = %s WHERE machine_id = %s AND id = %s",
            (_ts(samples[0].t), machine_id, open_ids["no_data"]),
        )
        messages.append(
            alert_message(organisation_id, open_ids["no_data"], machine_id, "no_data", "ended")
        )
    history: list[Sample] | None = None
    for kind, (duration, cond, text) in conds.items():
        is_open = kind in open_ids
        run_start: float | None = None
        first = cond(samples[0])
        if first is not None and not is_open and duration > 0:
            if history is None:
                history = _history(cur, machine_id, samples[0].t, _max_duration(rules))
            for s in reversed(history):
                if cond(s) is None:
                    break
                run_start = s.t
        for s in samples:
            value = cond(s)
            if value is None:
                run_start = None
                if is_open:
                    cur.execute(
                        "UPDATE alerts SET ended_at = %s WHERE machine_id = %s AND id = %s",
                        (_ts(s.t), machine_id, open_ids[kind]),
                    )
                    messages.append(
                        alert_message(organisation_id, open_ids[kind], machine_id, kind, "ended")
                    )
                    is_open = False
                    del open_ids[kind]
                continue
            if run_start is None:
                run_start = s.t
            if not is_open and s.t - run_start >= duration:
                cur.execute(
                    "INSERT INTO alerts (organisation_id, machine_id, job_id, kind, message,"
                    " value, started_at) VALUES (%s, %s, %s, %s, %s, %s, %s) RETURNING id",
                    (organisation_id, machine_id, job_id, kind, text, value, _ts(run_start)),
                )
                row = cur.fetchone()
                assert row is not None
                open_ids[kind] = row[0]
                is_open = True
                messages.append(
                    alert_message(
                        organisation_id, row[0], machine_id, kind, "started", text, value, job_id
                    )
                )
    return messages


def _max_duration(rules: AlertRules) -> float:
    return max(
        rules.rate_duration_s,
        rules.speed_duration_s,
        rules.saturation_duration_s,
        rules.fix_lost_duration_s,
    )


def _history(
    cur: psycopg.Cursor[Any], machine_id: int, before: float, span_s: float
) -> list[Sample]:
    """Stored records just before a batch, so a condition's run can span batches."""
    cur.execute(
        "SELECT extract(epoch FROM t)::float8, fix_quality, coalesce(speed_filtered_m_s,"
        " speed_raw_m_s), target_rate_kg_ha, applied_rate_kg_ha, implement_down, alarms"
        " FROM telemetry WHERE machine_id = %s AND t >= %s AND t < %s ORDER BY t",
        (machine_id, _ts(before - span_s - 1.0), _ts(before)),
    )
    return [Sample(r[0], r[1], r[2], r[3], r[4], r[5], r[6] or ()) for r in cur.fetchall()]


def alert_message(
    org: int,
    alert_id: int,
    machine_id: int,
    kind: str,
    event: str,
    message: str = "",
    value: float | None = None,
    job_id: int | None = None,
) -> dict[str, Any]:
    return {
        "type": "alert",
        "org": org,
        "id": alert_id,
        "machine_id": machine_id,
        "job_id": job_id,
        "kind": kind,
        "event": event,
        "message": message,
        "value": value,
    }


def notify(cur: psycopg.Cursor[Any], messages: list[dict[str, Any]]) -> None:
    """Queue live messages; PostgreSQL delivers them to every listener at commit.

    The messages go as one JSON array (``json`` keeps each element's text as written):
    a ``text[]`` parameter is escaped element by element in Python, which cost more than
    the NOTIFY itself on a thin request."""
    if messages:
        cur.execute(
            "SELECT pg_notify(%s, m::text) FROM json_array_elements(%s::json) AS m",
            (LIVE_CHANNEL, "[" + ",".join(json.dumps(m, default=str) for m in messages) + "]"),
        )


def check_no_data(conn: psycopg.Connection[Any], timeout_s: float, wait: bool = True) -> int:
    """Open ``no_data`` alerts for machines running a job but silent beyond the timeout.

    Idempotent and safe from several processes at once (the insert re-checks
    that no open alert exists under a transaction-level advisory lock).
    Returns the number of alerts opened. ``wait=False`` (read requests) skips the sweep
    when another one holds the lock instead of queueing behind it: that sweep does the
    same work.
    """
    with conn.transaction(), conn.cursor() as cur:
        if wait:
            cur.execute("SELECT pg_advisory_xact_lock(7002, 0)")
        else:
            cur.execute("SELECT pg_try_advisory_xact_lock(7002, 0)")
            row = cur.fetchone()
            if not (row and row[0]):
                return 0
        cur.execute(
            """
            INSERT INTO alerts (organisation_id, machine_id, job_id, kind, message, value)
            SELECT DISTINCT ON (j.machine_id) j.organisation_id, j.machine_id, j.id, 'no_data',
                   'no data from a machine running a job for more than ' || %s || ' s',
                   extract(epoch FROM now() - ms.last_seen_at)
            FROM jobs j
            LEFT JOIN machine_status ms ON ms.machine_id = j.machine_id
            WHERE j.state = 'running'
              AND (ms.last_seen_at IS NULL
                   OR ms.last_seen_at < now() - make_interval(secs => %s))
              AND NOT EXISTS (SELECT 1 FROM alerts a WHERE a.machine_id = j.machine_id
                              AND a.kind = 'no_data' AND a.ended_at IS NULL)
            ORDER BY j.machine_id, j.id
            RETURNING id, organisation_id, machine_id, job_id, message, value
            """,
            (f"{timeout_s:g}", timeout_s),
        )
        rows = cur.fetchall()
        # a machine that no longer runs a job is not "silent"
        cur.execute(
            """
            UPDATE alerts a SET ended_at = now()
            WHERE a.kind = 'no_data' AND a.ended_at IS NULL
              AND NOT EXISTS (SELECT 1 FROM jobs j WHERE j.machine_id = a.machine_id
                              AND j.state = 'running')
            RETURNING id, organisation_id, machine_id, job_id
            """
        )
        ended = cur.fetchall()
        notify(
            cur,
            [
                alert_message(org, aid, mid, "no_data", "ended", job_id=jid)
                for aid, org, mid, jid in ended
            ],
        )
        notify(
            cur,
            [
                alert_message(org, aid, mid, "no_data", "started", text, value, jid)
                for aid, org, mid, jid, text, value in rows
            ],
        )
    return len(rows)


def open_event(
    cur: psycopg.Cursor[Any],
    organisation_id: int,
    machine_id: int,
    job_id: int | None,
    kind: str,
    message: str,
    value: float | None = None,
) -> list[dict[str, Any]]:
    """Open an ``EVENT_KINDS`` alert for the machine unless one of that kind is open.
    Returns the live messages (empty when one was already open)."""
    # Two statements, not INSERT ... SELECT ... WHERE NOT EXISTS: past one node Citus pushes
    # that one-shard INSERT ... SELECT down to the machine's shard, where the int id's
    # sequence default cannot be evaluated; an INSERT ... VALUES takes its id on the
    # coordinator. The caller (ingest) holds the machine's advisory lock: nothing opens one
    # in between.
    cur.execute(
        "SELECT 1 FROM alerts WHERE machine_id = %s AND kind = %s AND ended_at IS NULL",
        (machine_id, kind),
    )
    if cur.fetchone() is not None:
        return []
    cur.execute(
        "INSERT INTO alerts (organisation_id, machine_id, job_id, kind, message, value)"
        " VALUES (%s, %s, %s, %s, %s, %s) RETURNING id",
        (organisation_id, machine_id, job_id, kind, message, value),
    )
    row = cur.fetchone()
    assert row is not None
    return [
        alert_message(organisation_id, row[0], machine_id, kind, "started", message, value, job_id)
    ]


def end_event(
    cur: psycopg.Cursor[Any], organisation_id: int, machine_id: int, alert_id: int, kind: str
) -> list[dict[str, Any]]:
    """End an ``EVENT_KINDS`` alert now; returns the live message."""
    cur.execute(
        "UPDATE alerts SET ended_at = now() WHERE machine_id = %s AND id = %s",
        (machine_id, alert_id),
    )
    return [alert_message(organisation_id, alert_id, machine_id, kind, "ended")]
