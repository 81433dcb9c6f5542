"""The batch's stream under the machine's lock: what is read of it before the batch
(``read_machine``), how far the ack moves (``advance``), and its row after the batch
(``stream_row``).

``acked_seq`` (per stream, ``telemetry_streams``) advances over the contiguous seqs that
are stored (or were rejected for good: resending them can never succeed, so the edge may
trim them; it counts them as rejected), and stops at the first gap. A new stream starts
just below its ``stream_start``.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable
from typing import Any

import orjson
import psycopg

from fieldrx.fleet import alerts as alert_rules
from fieldrx.fleet.ingest.model import MachineInfo, t_us, ts
from fieldrx.fleet.telemetry_row import PG_EPOCH, TelemetryRow

# every table's machine named as the parameter itself, not only through ``m.id``: past one
# node (Citus) the correlated subqueries otherwise plan as a multi-shard query
MACHINE_SQL = (
    "SELECT m.organisation_id, m.speed_min_m_s, m.speed_max_m_s, ts.acked_seq,"
    " extract(epoch FROM s.last_t)::float8,"
    " (SELECT coalesce(json_object_agg(a.kind, a.id), '{}') FROM alerts a"
    "   WHERE a.machine_id = %(m)s AND a.ended_at IS NULL),"
    " extract(epoch FROM ts.last_seen_at)::float8,"
    " (SELECT extract(epoch FROM max(o.last_seen_at))::float8 FROM telemetry_streams o"
    "   WHERE o.machine_id = %(m)s AND o.stream <> %(s)s),"
    " ts.max_seq, ts.first_t, ts.last_t"
    " FROM machines m"
    " LEFT JOIN machine_status s ON s.machine_id = m.id"
    " LEFT JOIN telemetry_streams ts ON ts.machine_id = m.id AND ts.stream = %(s)s"
    " WHERE m.id = %(m)s"
)


def read_machine(cur: psycopg.Cursor[Any], machine_id: int, stream: str) -> None:
    """Queue the read of the machine and the stream (its row: ``machine_info``)."""
    cur.execute(MACHINE_SQL, {"s": stream, "m": machine_id})


def machine_info(r: Any) -> MachineInfo | None:
    """``read_machine``'s row; None: no such machine."""
    if r is None:
        return None
    alerts = r[5] if isinstance(r[5], dict) else orjson.loads(r[5])
    events = {k: v for k, v in alerts.items() if k in alert_rules.EVENT_KINDS}
    conds = {k: v for k, v in alerts.items() if k not in events}
    return MachineInfo(
        r[0], r[1], r[2], r[3], r[4], conds, r[6], r[7], events, r[8],
        None if r[9] is None else t_us(r[9]), None if r[10] is None else t_us(r[10]),
    )  # fmt: skip


def advance(
    cur: psycopg.Cursor[Any],
    machine_id: int,
    stream: str,
    acked: int,
    done: set[int],
    info: MachineInfo,
    new: list[TelemetryRow],
) -> int:
    """Highest contiguous seq stored (or rejected for good), starting from the stored ack.

    Stored seqs above the ack are looked up only when there can be any (the stream's
    highest stored seq, with this batch's, is above it), within the stream's time range."""
    while acked + 1 in done:
        acked += 1
    top = max([info.max_seq or 0, *(r.seq for r in new)])
    if acked >= top:
        return acked
    us = [r.t for r in new]
    if info.first_us is not None:
        us += [info.first_us, info.last_us or info.first_us]
    if not us:  # nothing stored on the stream and nothing new: no seq above the ack
        return acked
    t0, t1 = ts(min(us)), ts(max(us))

    def stored_above(after: int) -> list[int]:
        cur.execute(
            "SELECT seq FROM telemetry WHERE machine_id = %s AND stream = %s AND seq > %s"
            " AND t BETWEEN %s AND %s ORDER BY seq LIMIT %s",
            (machine_id, stream, after, t0, t1, ACK_PAGE),
        )
        return [r[0] for r in cur.fetchall()]

    return advance_over_stored(stored_above, acked, done)


ACK_PAGE = 2000  # stored seqs read per step while the ack walks over them


def advance_over_stored(
    stored_above: Callable[[int], list[int]], acked: int, done: set[int]
) -> int:
    """Move ``acked`` over the contiguous seqs that are stored (``stored_above(a)``: the
    stream's stored seqs above ``a``, ascending, at most ``ACK_PAGE``) or in ``done``;
    stop at the first gap. Shared by telemetry and the thin profile's cell records."""
    while acked + 1 in done:
        acked += 1
    while True:
        seqs = stored_above(acked)
        moved = False
        for s in seqs:
            if s == acked + 1:
                acked = s
                moved = True
                while acked + 1 in done:
                    acked += 1
            elif s > acked + 1:
                return acked
        if not moved or len(seqs) < ACK_PAGE:
            return acked


def stream_row(
    machine_id: int, stream: str, stream_start: int, acked: int, new: list[TelemetryRow]
) -> tuple[str, tuple[Any, ...]]:
    """The upsert of the stream's acknowledged seq, last batch time, record count and time
    span (statement, parameters)."""
    t0 = t1 = None
    if new:
        us = [r.t for r in new]
        t0 = dt.datetime.fromtimestamp(min(us) / 1e6 + PG_EPOCH, dt.UTC)
        t1 = dt.datetime.fromtimestamp(max(us) / 1e6 + PG_EPOCH, dt.UTC)
    return (
        "INSERT INTO telemetry_streams AS ts (machine_id, stream, first_seq, acked_seq,"
        " n_records, first_t, last_t, max_seq) VALUES (%s, %s, %s, %s, %s, %s, %s, %s)"
        " ON CONFLICT (machine_id, stream) DO UPDATE SET acked_seq = excluded.acked_seq,"
        " last_seen_at = excluded.last_seen_at, n_records = ts.n_records + excluded.n_records,"
        " first_t = least(ts.first_t, excluded.first_t),"
        " last_t = greatest(ts.last_t, excluded.last_t),"
        " max_seq = greatest(ts.max_seq, excluded.max_seq)",
        (
            machine_id, stream, stream_start if stream else 1, acked, len(new), t0, t1,
            max(r.seq for r in new) if new else None,
        ),
    )  # fmt: skip
