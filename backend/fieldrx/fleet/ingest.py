"""Telemetry ingest shared by HTTP and MQTT: validate, COPY, deduplicate, acknowledge.

One batch is one transaction:

1. every record is validated on its own (``TelemetryRecord`` rules plus the
   column types); a bad record is rejected with a reason, the rest goes on;
2. a transaction-level advisory lock per machine serialises concurrent
   batches of the same machine (two MQTT workers, a retry racing the
   original), so the already-stored seqs can be read once and the new rows
   COPied straight into ``telemetry`` with COPY BINARY (EWKB points), the
   fastest path measured here (shared/STACK.md) — no staging table needed;
3. ``acked_seq`` advances over the contiguous seqs that are stored (or were
   rejected for good: resending them can never succeed, so the edge may trim
   them; it counts them as rejected), and stops at the first gap;
4. machine status, per-cell aggregates, job progress and alerts are updated and
   live messages are queued with NOTIFY, all in the same transaction.

A record whose ``machine_id`` differs from the sending machine (the device
token's, or the MQTT topic's) is rejected on its own and does not advance
``acked_seq``: a device can only write its own machine's records.
"""

from __future__ import annotations

import datetime as dt
import operator
import struct
import time
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from typing import Any

import orjson
import psycopg
from fieldrx_edge.protocol import (
    _FIELD_SET,
    _FLOAT_FIELDS,
    ALARMS,
    EXTRA_FIELDS,
    TELEMETRY_FIELDS,
    TelemetryAck,
    TelemetryRecord,
)

from fieldrx.fleet import alerts as alert_rules

COLUMNS = (
    "machine_id",
    "seq",
    "t",
    "job_id",
    "geom",
    "fix_quality",
    "hdop",
    "speed_raw_m_s",
    "speed_filtered_m_s",
    "heading_deg",
    "cell_seq",
    "target_rate_kg_ha",
    "applied_rate_kg_ha",
    "target_shaft_rpm",
    "actual_shaft_rpm",
    "duty",
    "ndvi",
    "depth_mm",
    "implement_down",
    "alarms",
    "queue_backlog",
    *EXTRA_FIELDS,  # optional sensor-job fields (issue 13), last so row indexes stay put
)
# t goes as int8 microseconds since 2000-01-01: the binary form of timestamptz, without
# building a datetime per record; geom goes as raw EWKB bytes (geometry_recv reads EWKB).
COPY_TYPES = (
    "int4",
    "int8",
    "int8",
    "int4",
    "bytea",
    "int2",
    "float8",
    "float8",
    "float8",
    "float8",
    "int4",
    "float8",
    "float8",
    "float8",
    "float8",
    "float8",
    "float8",
    "float8",
    "bool",
    "varchar[]",
    "int4",
    *("float8",) * len(EXTRA_FIELDS),
)
COPY_SQL = f"COPY telemetry ({', '.join(COLUMNS)}) FROM STDIN (FORMAT BINARY)"

PG_EPOCH = 946684800.0  # 2000-01-01T00:00:00Z
T_MAX = 4102444800.0  # 2100-01-01: anything later is a clock error
INT4_MAX = 2**31 - 1
INT8_MAX = 2**63 - 1
_EWKB_POINT = struct.Struct("<BIIdd")  # little endian, Point with SRID flag, SRID, x, y
_ALARM_SET = frozenset(ALARMS)
_LOCK_NS = 7001  # advisory lock namespace for per-machine ingest


class IngestError(ValueError):
    """The request as a whole is unusable (not JSON, no "records" list)."""


@dataclass
class IngestResult:
    machine_id: int
    acked_seq: int
    stored: int = 0
    duplicates: int = 0
    rejected: list[dict[str, Any]] = field(default_factory=list)

    def ack(self) -> TelemetryAck:
        return TelemetryAck(
            machine_id=self.machine_id,
            acked_seq=self.acked_seq,
            stored=self.stored,
            duplicates=self.duplicates,
            rejected=self.rejected,
        )

    def to_json(self) -> bytes:
        return orjson.dumps(asdict(self.ack()))


def parse_body(body: bytes | str) -> list[Any]:
    """``{"records": [...]}`` -> the list; anything else is an ``IngestError``."""
    try:
        obj = orjson.loads(body)
    except orjson.JSONDecodeError as exc:
        raise IngestError(f"body is not valid JSON: {exc}") from exc
    if not isinstance(obj, dict) or not isinstance(obj.get("records"), list):
        raise IngestError('body must be a JSON object {"records": [TelemetryRecord, ...]}')
    return obj["records"]


_GET_ALL = operator.itemgetter(*TELEMETRY_FIELDS)
_N_FIELDS = len(TELEMETRY_FIELDS)
_FLOAT_TYPES = frozenset({float, type(None)})
_NO_EXTRAS = (None,) * len(EXTRA_FIELDS)  # records with extras take the general path
assert TELEMETRY_FIELDS == (
    "machine_id", "seq", "t", "lon", "lat", "fix_quality", "hdop", "speed_raw_m_s",
    "speed_filtered_m_s", "heading_deg", "job_id", "cell_seq", "target_rate_kg_ha",
    "applied_rate_kg_ha", "target_shaft_rpm", "actual_shaft_rpm", "duty", "ndvi", "depth_mm",
    "implement_down", "alarms", "queue_backlog",
)  # fmt: skip


def _fast_row(d: Any, machine_id: int) -> tuple[Any, ...] | None:
    """A complete, plainly typed record (what agents send) -> COPY row; else None.

    None means "not sure": the general path decides. Floats must be floats here
    and their sum finite (NaN and inf propagate through a sum).
    """
    if type(d) is not dict or len(d) != _N_FIELDS or not (d.keys() <= _FIELD_SET):
        return None
    (m, s, t, lon, lat, fq, hdop, sraw, sfil, head, job, cell, trate, arate, trpm, arpm, duty,
     ndvi, depth, down, alarms, backlog) = _GET_ALL(d)  # fmt: skip
    if (
        m != machine_id
        or type(s) is not int
        or not 1 <= s <= INT8_MAX
        or type(t) is not float
        or not 0.0 < t < T_MAX
        or type(fq) is not int
        or not 0 <= fq <= 32767
        or type(down) is not bool
        or type(backlog) is not int
        or not 0 <= backlog <= INT4_MAX
        or type(alarms) is not list
        or (alarms and not _ALARM_SET.issuperset(alarms))
        or (job is not None and (type(job) is not int or not 0 < job <= INT4_MAX))
        or (cell is not None and (type(cell) is not int or not -INT4_MAX <= cell <= INT4_MAX))
    ):
        return None
    floats = (hdop, sraw, sfil, head, trate, arate, trpm, arpm, duty, ndvi, depth)
    if not _FLOAT_TYPES.issuperset(map(type, floats)):
        return None
    total = sum(filter(None, floats))
    if total - total != 0.0:
        return None
    if lon is None:
        if lat is not None:
            return None
        geom = None
    else:
        if type(lon) is not float or type(lat) is not float:
            return None
        if not (-180.0 <= lon <= 180.0 and -90.0 <= lat <= 90.0):
            return None
        geom = _EWKB_POINT.pack(1, 0x20000001, 4326, lon, lat)
    return (
        m, s, int((t - PG_EPOCH) * 1e6), job, geom, fq, hdop, sraw, sfil, head, cell, trate,
        arate, trpm, arpm, duty, ndvi, depth, down, alarms, backlog, *_NO_EXTRAS,
    )  # fmt: skip


def _slow_row(d: Any, machine_id: int) -> tuple[Any, ...] | str:
    """Any record: the protocol's own validation, then the column ranges. Row or reason."""
    try:
        rec = TelemetryRecord.from_dict(d)
    except Exception as exc:  # ProtocolError, or TypeError/OverflowError from odd values
        return str(exc) or type(exc).__name__
    if rec.machine_id != machine_id:
        return f"machine_id {rec.machine_id} is not this device's machine ({machine_id})"
    if rec.seq > INT8_MAX:
        return f"seq {rec.seq} out of range"
    if rec.t >= T_MAX:
        return f"t {rec.t!r} is after 2100: clock error"
    fq = rec.fix_quality
    if type(fq) is not int or not 0 <= fq <= 32767:
        return f"fix_quality must be an integer 0..32767, got {fq!r}"
    job = rec.job_id
    if job is not None and (type(job) is not int or not 0 < job <= INT4_MAX):
        return f"job_id must be a positive integer or null, got {job!r}"
    cell = rec.cell_seq
    if cell is not None and (type(cell) is not int or not -INT4_MAX <= cell <= INT4_MAX):
        return f"cell_seq must be an integer or null, got {cell!r}"
    if type(rec.implement_down) is not bool:
        return f"implement_down must be true or false, got {rec.implement_down!r}"
    backlog = rec.queue_backlog
    if type(backlog) is not int or not 0 <= backlog <= INT4_MAX:
        return f"queue_backlog must be a non-negative integer, got {backlog!r}"
    try:
        f = [None if v is None else float(v) for v in (getattr(rec, n) for n in _FLOAT_FIELDS)]
    except OverflowError:
        return "a number is too large"
    geom = None
    if rec.lon is not None and rec.lat is not None:
        geom = _EWKB_POINT.pack(1, 0x20000001, 4326, float(rec.lon), float(rec.lat))
    return (
        rec.machine_id,
        rec.seq,
        int((rec.t - PG_EPOCH) * 1e6),
        job,
        geom,
        fq,
        *f[:4],
        cell,
        *f[4:11],
        rec.implement_down,
        list(rec.alarms),
        backlog,
        *f[11:],
    )


def validate(
    raw: Iterable[Any], machine_id: int
) -> tuple[dict[int, tuple[Any, ...]], list[dict[str, Any]], set[int], int]:
    """Split records into valid rows by seq, rejects, rejected-for-good seqs and in-batch repeats.

    The fast path takes complete, plainly typed records; everything else goes
    through ``TelemetryRecord.from_dict`` (same rules, same messages) and the
    column ranges.
    """
    rows: dict[int, tuple[Any, ...]] = {}
    rejected: list[dict[str, Any]] = []
    dead: set[int] = set()
    repeats = 0
    for d in raw:
        r = _fast_row(d, machine_id)
        if r is None:
            r = _slow_row(d, machine_id)
            if type(r) is str:
                seq = d.get("seq") if isinstance(d, dict) else None
                if type(seq) is not int or seq < 1:
                    seq = None
                rejected.append({"seq": seq, "reason": r})
                mid = d.get("machine_id") if isinstance(d, dict) else None
                if seq is not None and (mid is None or mid == machine_id):
                    dead.add(seq)
                continue
        if r[1] in rows:
            repeats += 1
        else:
            rows[r[1]] = r
    return rows, rejected, dead, repeats


@dataclass
class MachineInfo:
    organisation_id: int
    speed_min_m_s: float
    speed_max_m_s: float
    acked_seq: int
    last_t: float | None
    open_alerts: dict[str, int]


def _lock_machine(cur: psycopg.Cursor[Any], machine_id: int) -> MachineInfo | None:
    """Take the machine's ingest lock and read what this batch needs, in one round trip."""
    cur.execute(
        "SELECT m.organisation_id, m.speed_min_m_s, m.speed_max_m_s, coalesce(s.acked_seq, 0),"
        " extract(epoch FROM s.last_t)::float8,"
        " (SELECT coalesce(json_object_agg(a.kind, a.id), '{}') FROM alerts a"
        "   WHERE a.machine_id = m.id AND a.ended_at IS NULL)"
        " FROM (SELECT pg_advisory_xact_lock(%s, %s)) AS lock, machines m"
        " LEFT JOIN machine_status s ON s.machine_id = m.id WHERE m.id = %s",
        (_LOCK_NS, machine_id, machine_id),
    )
    r = cur.fetchone()
    return None if r is None else MachineInfo(*r)


def ingest(conn: psycopg.Connection[Any], machine_id: int, raw: list[Any]) -> IngestResult:
    """Store one batch for ``machine_id`` (already authenticated) and return the ack."""
    rows, rejected, dead, repeats = validate(raw, machine_id)
    with conn.transaction(), conn.cursor() as cur:
        info = _lock_machine(cur, machine_id)
        if info is None:
            raise IngestError(f"machine {machine_id} does not exist")
        result = IngestResult(machine_id, info.acked_seq, rejected=rejected, duplicates=repeats)
        new: list[tuple[Any, ...]] = []
        if rows:
            lo, hi = min(rows), max(rows)
            cur.execute(
                "SELECT seq FROM telemetry WHERE machine_id = %s AND seq BETWEEN %s AND %s",
                (machine_id, lo, hi),
            )
            existing = {r[0] for r in cur.fetchall()}
            result.duplicates += len(existing.intersection(rows))
            new = [rows[s] for s in sorted(rows) if s not in existing]
        if new:
            with cur.copy(COPY_SQL) as copy:
                copy.set_types(COPY_TYPES)
                write = copy.write_row
                for r in new:
                    write(r)
        result.stored = len(new)
        result.acked_seq = _advance(cur, machine_id, info.acked_seq, set(rows) | dead)
        messages: list[dict[str, Any]] = []
        _status(cur, machine_id, info, new, result.acked_seq)
        if new:
            latest = max(new, key=lambda r: r[2])
            messages.append(_position(info.organisation_id, latest, result))
            messages.extend(_cells(cur, machine_id, info.organisation_id, new))
        if new and _may_alert(new, info):
            samples = [
                alert_rules.Sample(
                    r[2] / 1e6 + PG_EPOCH,
                    r[5],
                    r[8] if r[8] is not None else r[7],
                    r[11],
                    r[12],
                    r[18],
                    r[19],
                )
                for r in sorted(new, key=lambda r: r[2])
            ]
            messages.extend(
                alert_rules.evaluate(
                    cur,
                    machine_id,
                    info.organisation_id,
                    latest[3],
                    samples,
                    info.speed_min_m_s,
                    info.speed_max_m_s,
                    info.open_alerts,
                )
            )
        if new and any(r[17] is not None for r in new):  # depths: seeding job (issue 13)
            from fieldrx.fleet.seed_alerts import check_depth_window

            messages.extend(
                check_depth_window(
                    cur, machine_id, info.organisation_id, latest[3], info.open_alerts
                )
            )
        alert_rules.notify(cur, messages)
    return result


def _may_alert(new: list[tuple[Any, ...]], info: MachineInfo) -> bool:
    """Cheap pre-check: could any alert open or close with this batch? (Most batches: no.)"""
    if info.open_alerts:
        return True
    lo, hi = info.speed_min_m_s, info.speed_max_m_s
    tol = alert_rules.RULES.rate_tolerance
    for r in new:
        if r[5] == 0 or r[19]:  # no fix, or any alarm from the agent
            return True
        if r[18]:
            v = r[8] if r[8] is not None else r[7]
            if v is not None and (v < lo or v > hi):
                return True
            tr, ar = r[11], r[12]
            if tr is not None and ar is not None and tr > 0 and abs(ar - tr) > tol * tr:
                return True
    return False


def _advance(cur: psycopg.Cursor[Any], machine_id: int, acked: int, done: set[int]) -> int:
    """Highest contiguous seq stored (or rejected for good), starting from the stored ack."""
    while acked + 1 in done:
        acked += 1
    while True:
        cur.execute(
            "SELECT seq FROM telemetry WHERE machine_id = %s AND seq > %s ORDER BY seq LIMIT 2000",
            (machine_id, acked),
        )
        seqs = [r[0] for r in cur.fetchall()]
        moved = False
        for s in seqs:
            if s == acked + 1:
                acked = s
                moved = True
                while acked + 1 in done:
                    acked += 1
            elif s > acked + 1:
                return acked
        if not moved or len(seqs) < 2000:
            return acked


def _status(
    cur: psycopg.Cursor[Any],
    machine_id: int,
    info: MachineInfo,
    new: list[tuple[Any, ...]],
    acked: int,
) -> None:
    """Upsert the machine's latest state; position fields only move forward in record time."""
    if not new:
        cur.execute(
            "INSERT INTO machine_status (machine_id, last_seen_at, acked_seq, queue_backlog,"
            " alarms) VALUES (%s, now(), %s, 0, '{}') ON CONFLICT (machine_id) DO UPDATE"
            " SET last_seen_at = now(), acked_seq = excluded.acked_seq",
            (machine_id, acked),
        )
        return
    r = max(new, key=lambda r: r[2])
    t = r[2] / 1e6 + PG_EPOCH
    if info.last_t is not None and t < info.last_t:
        cur.execute(
            "UPDATE machine_status SET last_seen_at = now(), acked_seq = %s WHERE machine_id = %s",
            (acked, machine_id),
        )
        return
    lon = lat = None
    if r[4] is not None:
        _, _, _, lon, lat = _EWKB_POINT.unpack(r[4])
    cur.execute(
        """
        INSERT INTO machine_status (machine_id, last_seen_at, last_t, acked_seq, lon, lat,
            speed_m_s, heading_deg, job_id, cell_seq, target_rate_kg_ha, applied_rate_kg_ha,
            queue_backlog, alarms)
        VALUES (%s, now(), %s, %s, %s, %s, %s, %s, %s, %s, %s, %s, %s, %s)
        ON CONFLICT (machine_id) DO UPDATE SET last_seen_at = now(), last_t = excluded.last_t,
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
            r[8] if r[8] is not None else r[7],
            r[9],
            r[3],
            r[10],
            r[11],
            r[12],
            r[20],
            r[19],
        ),
    )


def _position(org: int, r: tuple[Any, ...], result: IngestResult) -> dict[str, Any]:
    lon = lat = None
    if r[4] is not None:
        _, _, _, lon, lat = _EWKB_POINT.unpack(r[4])
    return {
        "type": "position",
        "org": org,
        "machine_id": r[0],
        "seq": r[1],
        "t": r[2] / 1e6 + PG_EPOCH,
        "lon": lon,
        "lat": lat,
        "fix_quality": r[5],
        "speed_m_s": r[8] if r[8] is not None else r[7],
        "heading_deg": r[9],
        "job_id": r[3],
        "cell_seq": r[10],
        "target_rate_kg_ha": r[11],
        "applied_rate_kg_ha": r[12],
        "ndvi": r[16],  # sensor jobs (issue 13): the fleet view shows the kind's own figure
        "depth_mm": r[17],
        "implement_down": r[18],
        "alarms": r[19],
        "queue_backlog": r[20],
        "acked_seq": result.acked_seq,
        "stored": result.stored,
        "sent_at": time.time(),
    }


def _cells(
    cur: psycopg.Cursor[Any], machine_id: int, org: int, new: list[tuple[Any, ...]]
) -> list[dict[str, Any]]:
    """Add the batch to the per-cell aggregates of this machine's jobs; update job progress.

    Only records with a job, a cell and the implement down count. A cell counts
    as applied once it has received a positive applied rate.
    """
    agg: dict[tuple[int, int], list[Any]] = {}
    for r in new:
        if r[3] is None or r[10] is None or not r[18]:
            continue
        key = (r[3], r[10])
        a = agg.get(key)
        tr = r[11] or 0.0
        ar = r[12] or 0.0
        if a is None:
            agg[key] = [1, tr, ar, r[2], r[2]]
        else:
            a[0] += 1
            a[1] += tr
            a[2] += ar
            if r[2] < a[3]:
                a[3] = r[2]
            if r[2] > a[4]:
                a[4] = r[2]
    if not agg:
        return []
    items = list(agg.items())

    def ts(us: int) -> dt.datetime:
        return dt.datetime.fromtimestamp(us / 1e6 + PG_EPOCH, dt.UTC)

    cur.execute(
        """
        WITH new AS (
            SELECT * FROM unnest(%s::int[], %s::int[], %s::int[], %s::float8[], %s::float8[],
                                 %s::timestamptz[], %s::timestamptz[])
                AS n(job_id, seq, n, ts, aps, ft, lt)
            WHERE n.job_id IN (SELECT id FROM jobs WHERE machine_id = %s)  -- this machine's jobs
        ), old AS (
            SELECT c.job_id, c.seq, c.applied_rate_sum FROM job_cells_applied c
            JOIN new USING (job_id, seq)
        ), up AS (
            INSERT INTO job_cells_applied AS c (job_id, seq, n_records, target_rate_sum,
                applied_rate_sum, first_t, last_t)
            SELECT job_id, seq, n, ts, aps, ft, lt FROM new
            ON CONFLICT (job_id, seq) DO UPDATE SET
                n_records = c.n_records + excluded.n_records,
                target_rate_sum = c.target_rate_sum + excluded.target_rate_sum,
                applied_rate_sum = c.applied_rate_sum + excluded.applied_rate_sum,
                first_t = least(c.first_t, excluded.first_t),
                last_t = greatest(c.last_t, excluded.last_t)
            RETURNING c.job_id, c.seq, c.applied_rate_sum
        ), gained AS (
            SELECT up.job_id, count(*) AS k FROM up LEFT JOIN old USING (job_id, seq)
            WHERE up.applied_rate_sum > 0 AND coalesce(old.applied_rate_sum, 0) <= 0
            GROUP BY up.job_id
        )
        UPDATE jobs j SET cells_applied = j.cells_applied + gained.k, updated_at = now()
        FROM gained WHERE j.id = gained.job_id
        RETURNING j.id, j.state, j.cells_applied, j.n_cells
        """,
        (
            [k[0] for k, _ in items],
            [k[1] for k, _ in items],
            [v[0] for _, v in items],
            [v[1] for _, v in items],
            [v[2] for _, v in items],
            [ts(v[3]) for _, v in items],
            [ts(v[4]) for _, v in items],
            machine_id,
        ),
    )
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
        for jid, state, applied, n in cur.fetchall()
    ]


def raw_copy(conn: psycopg.Connection[Any], rows: list[tuple[Any, ...]]) -> None:
    """Plain COPY BINARY of prepared rows into ``telemetry``: the benchmark's baseline."""
    with conn.transaction(), conn.cursor() as cur, cur.copy(COPY_SQL) as copy:
        copy.set_types(COPY_TYPES)
        for r in rows:
            copy.write_row(r)
