"""Telemetry ingest shared by HTTP and MQTT: validate, COPY, deduplicate, acknowledge.

A batch names its stream (telemetry format 2, ``fieldrx_edge.protocol``): the
random id of the agent queue that numbered its records. Records are keyed by
(machine, stream, seq); a batch without a stream (format 1 agents) belongs to
the machine's legacy stream ''. One batch is one transaction:

1. every record is validated on its own (``TelemetryRecord`` rules plus the
   column types, and a record time no more than ``FUTURE_TOLERANCE_S`` ahead
   of the server clock); a bad record is rejected with a reason, the rest goes
   on. A body with NaN/Infinity tokens (not JSON, but what an older agent may
   have queued) is still read, so only those records are rejected;
2. a transaction-level advisory lock per machine serialises concurrent
   batches of the same machine (two MQTT workers, a retry racing the
   original, two agents), so the stream's stored seqs can be read once and
   the new rows COPied straight into ``telemetry`` with COPY BINARY (EWKB
   points), the fastest path measured here (docs/architecture.md, "Stack notes"). ``telemetry``
   is partitioned by day (``fleet.partitions``): the records' days are made
   first if missing, and the seq lookups name a time range so they read only
   the stream's days: none at all for a batch above the stream's highest
   stored seq (the common case), the batch's own time range for resends,
   the stream's first..last record time otherwise;
3. a seq already stored on the stream is a duplicate only if it is the same
   record (same fix time); if it holds another record the stream's numbering
   went backwards (restored or cloned queue): nothing from that seq on is
   stored or acknowledged, and the ack says ``stream_conflict`` so the agent
   moves to a new stream;
4. ``acked_seq`` (per stream, ``telemetry_streams``) advances over the
   contiguous seqs that are stored (or were rejected for good: resending them
   can never succeed, so the edge may trim them; it counts them as rejected),
   and stops at the first gap. A new stream starts just below its
   ``stream_start``;
5. machine status, per-cell aggregates, job progress, the stream's row and
   alerts are updated (two streams sending at once for one machine open a
   ``duplicate_stream`` alert: both are kept) and live messages are queued with
   NOTIFY, all in the same transaction.

A record whose ``machine_id`` differs from the sending machine (the device
token's, or the MQTT topic's) is rejected on its own and does not advance
``acked_seq``: a device can only write its own machine's records.
"""

from __future__ import annotations

import datetime as dt
import json
import operator
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Protocol

import orjson
import psycopg
from fieldrx_edge.protocol import (
    ALARMS,
    CELL_FORMAT_VERSION,
    EXTRA_FIELDS,
    FLOAT_FIELDS,
    MAX_BATCHES,
    MAX_FIX_PERIOD_S,
    MULTI_KIND,
    STREAM_RE,
    TELEMETRY_FIELDS,
    TELEMETRY_FORMAT_VERSION,
    VALUE_RANGES,
    TelemetryAck,
    TelemetryRecord,
)

from fieldrx.fleet import alerts as alert_rules
from fieldrx.fleet.partitions import (
    FAR_PAST_REASON,
    ON_DEMAND_DAYS,
    ensure_days,
    is_far_past,
    job_spans_sql,
)
from fieldrx.fleet.telemetry_row import (
    PG_EPOCH,
    TELEMETRY_COPY,
    TelemetryRow,
    ewkb_point,
    make_row,
)

# the telemetry columns and their COPY types: one list (fleet.telemetry_row)
COLUMNS = TELEMETRY_COPY.columns
COPY_TYPES = TELEMETRY_COPY.types
COPY_SQL = TELEMETRY_COPY.sql()

_PG_EPOCH_DT = dt.datetime(2000, 1, 1, tzinfo=dt.UTC)
# a record time this far ahead of the server clock is a clock error: stored, it would
# become the machine's latest state until real time caught up
FUTURE_TOLERANCE_S = 300.0
CONCURRENT_WINDOW_S = 60.0  # two streams both sending within this: a duplicate_stream alert
# job kinds whose progress counts the cells the implement worked in, not the cells that got
# a positive applied rate (seed 000 topdressing, seed 002 seeding): see ``_cells``
PROGRESS_BY_WORK = ("ndvi_topdress", "seeding_depth")
INT4_MAX = 2**31 - 1
INT8_MAX = 2**63 - 1
_ALARM_SET = frozenset(ALARMS)
LOCK_NS = 7001  # advisory lock namespace for per-machine ingest


# each float field's accepted range, in FLOAT_FIELDS order (the protocol's VALUE_RANGES:
# what the agent clamps to), so a value outside is refused with its reason, never stored
_RANGES = tuple((name, *VALUE_RANGES[name]) for name in FLOAT_FIELDS)


def range_error(values: Any) -> str | None:
    """The first float field (in FLOAT_FIELDS order) outside its range, as a reason."""
    for (name, lo, hi), v in zip(_RANGES, values, strict=False):
        if v is not None and not lo <= v <= hi:
            return f"{name} {v!r} is out of range [{lo:g}, {hi:g}]"
    return None


class IngestError(ValueError):
    """The request as a whole is unusable (not JSON, no "records" list)."""


@dataclass
class IngestResult:
    machine_id: int
    acked_seq: int
    stored: int = 0
    duplicates: int = 0
    rejected: list[dict[str, Any]] = field(default_factory=list)
    stream: str = ""
    stream_conflict: bool = False
    streamed: bool = False  # the batch was format 2: the ack names its stream
    flagged: list[dict[str, Any]] = field(default_factory=list)  # stored, but see reason

    def ack(self) -> TelemetryAck:
        return TelemetryAck(
            machine_id=self.machine_id,
            acked_seq=self.acked_seq,
            stored=self.stored,
            duplicates=self.duplicates,
            rejected=self.rejected,
            stream=self.stream,
            stream_conflict=self.stream_conflict,
            flagged=self.flagged,
        )

    def to_json(self) -> bytes:
        """The ack as the agent reads it (``TelemetryAck``'s fields in order). orjson writes
        the dataclass itself: ``asdict`` deep-copied the rejects first, ~4 % of an API
        worker's CPU per thin request (py-spy, docs/scale.md section 5)."""
        if self.streamed:
            return orjson.dumps(self.ack())
        # a format 1 agent parses the ack strictly: only its fields
        return orjson.dumps(
            {
                "machine_id": self.machine_id,
                "acked_seq": self.acked_seq,
                "stored": self.stored,
                "duplicates": self.duplicates,
                "rejected": self.rejected,
            }
        )


@dataclass
class Batch:
    records: list[Any]
    stream: str = ""
    stream_start: int = 1
    streamed: bool = False
    kind: str = "telemetry"  # "cells": uplink profile thin's cell records (fleet.cellrecords)


def _loads(body: bytes | bytearray | str) -> Any:
    try:
        return orjson.loads(body)
    except orjson.JSONDecodeError as exc:
        # NaN / Infinity tokens (Python's json.dumps writes them): read them so the
        # records holding them are rejected one by one, not the whole batch
        try:
            return json.loads(body)
        except (ValueError, RecursionError):  # nesting deeper than the interpreter's stack
            raise IngestError(f"body is not valid JSON: {exc}") from exc


def parse_batch(body: bytes | bytearray | str) -> Batch:
    """``{"records": [...], "stream": id, "stream_start": n}`` (stream optional) -> Batch;
    anything else is an ``IngestError``."""
    return _batch_of(_loads(body))


def parse_request(body: bytes | str) -> list[Batch] | Batch:
    """An HTTP body: one batch (``parse_batch``) or several in one request
    (``{"format": 3, "kind": "batches", "batches": [batch, ...]}``, protocol.MULTI_KIND: a
    thin agent's track and cell batches) -> their list."""
    obj = _loads(body)
    if not isinstance(obj, dict) or obj.get("kind") != MULTI_KIND:
        return _batch_of(obj)
    if obj.get("format") != CELL_FORMAT_VERSION:
        raise IngestError(
            f"a {MULTI_KIND!r} request must be format {CELL_FORMAT_VERSION},"
            f" got {obj.get('format')!r}"
        )
    items = obj.get("batches")
    if not isinstance(items, list) or not 1 <= len(items) <= MAX_BATCHES:
        raise IngestError(f'"batches" must be a list of 1..{MAX_BATCHES} batches')
    out = []
    for i, item in enumerate(items):
        try:
            if isinstance(item, dict) and item.get("kind") == MULTI_KIND:
                raise IngestError("batches do not nest")
            out.append(_batch_of(item))
        except IngestError as exc:
            raise IngestError(f"batches[{i}]: {exc}") from exc
    return out


def _batch_of(obj: Any) -> Batch:
    if not isinstance(obj, dict) or not isinstance(obj.get("records"), list):
        raise IngestError('body must be a JSON object {"records": [TelemetryRecord, ...]}')
    fmt = obj.get("format", 1)
    kind = obj.get("kind", "telemetry")
    if kind == "cells":  # thin profile (format 3): same stream rules, fleet.cellrecords stores
        if fmt != CELL_FORMAT_VERSION:
            raise IngestError(f"a cells batch must be format {CELL_FORMAT_VERSION}, got {fmt!r}")
    elif kind != "telemetry":
        raise IngestError(f"kind {kind!r} is not 'telemetry' or 'cells'")
    elif type(fmt) is int and fmt > TELEMETRY_FORMAT_VERSION:  # a newer agent
        raise IngestError(
            f"format {fmt!r} not supported (1..{TELEMETRY_FORMAT_VERSION}): upgrade the server"
        )
    elif type(fmt) is not int or fmt < 1:  # not a format at all: upgrading would not help
        raise IngestError(f"format must be an integer 1..{TELEMETRY_FORMAT_VERSION}, got {fmt!r}")
    stream = obj.get("stream")
    if stream is None:
        if kind == "cells":
            raise IngestError("a cells batch must name its stream")
        return Batch(obj["records"])
    if not isinstance(stream, str) or not STREAM_RE.match(stream):
        raise IngestError(f"stream must be 1-32 characters [0-9A-Za-z_-], got {stream!r}")
    start = obj.get("stream_start", 1)
    if type(start) is not int or not 1 <= start <= INT8_MAX:
        raise IngestError(f"stream_start must be a positive integer, got {start!r}")
    return Batch(obj["records"], stream, start, True, kind)


_GET_ALL = operator.itemgetter(*TELEMETRY_FIELDS)
_GET_V1 = operator.itemgetter(*TELEMETRY_FIELDS[:-1])  # format 1: no fix_period_s
_N_FIELDS = len(TELEMETRY_FIELDS)
_FLOAT_TYPES = frozenset({float, type(None)})
_NO_EXTRAS = (None,) * len(EXTRA_FIELDS)  # records with extras take the general path
assert TELEMETRY_FIELDS == (
    "machine_id", "seq", "t", "lon", "lat", "fix_quality", "hdop", "speed_raw_m_s",
    "speed_filtered_m_s", "heading_deg", "job_id", "cell_seq", "target_rate_kg_ha",
    "applied_rate_kg_ha", "target_shaft_rpm", "actual_shaft_rpm", "duty", "ndvi", "depth_mm",
    "implement_down", "alarms", "queue_backlog", "fix_period_s",
)  # fmt: skip


def _fast_row(d: Any, machine_id: int, t_max: float, stream: str) -> TelemetryRow | None:
    """A complete, plainly typed record (what agents send) -> COPY row; else None.

    None means "not sure": the general path decides. Floats must be floats here
    and their sum finite (NaN and inf propagate through a sum).
    """
    if type(d) is not dict:
        return None
    # n keys, all n fields present: exactly the fields (no subset test)
    n = len(d)
    try:
        if n == _N_FIELDS:
            values = _GET_ALL(d)
        elif n == _N_FIELDS - 1:
            values = (*_GET_V1(d), None)
        else:
            return None
    except KeyError:
        return None
    (m, s, t, lon, lat, fq, hdop, sraw, sfil, head, job, cell, trate, arate, trpm, arpm, duty,
     ndvi, depth, down, alarms, backlog, period) = values  # fmt: skip
    if (
        m != machine_id
        or type(s) is not int
        or not 1 <= s <= INT8_MAX
        or type(t) is not float
        or not 0.0 < t < t_max
        or type(fq) is not int
        or not 0 <= fq <= 32767
        or type(down) is not bool
        or type(backlog) is not int
        or not 0 <= backlog <= INT4_MAX
        or type(alarms) is not list
        or (alarms and not _ALARM_SET.issuperset(alarms))
        or (job is not None and (type(job) is not int or not 0 < job <= INT4_MAX))
        or (cell is not None and (type(cell) is not int or not -INT4_MAX <= cell <= INT4_MAX))
        or (period is not None and (type(period) is not float or not 0.0 < period <= 60.0))
    ):
        return None
    floats = (hdop, sraw, sfil, head, trate, arate, trpm, arpm, duty, ndvi, depth)
    if not _FLOAT_TYPES.issuperset(map(type, floats)):
        return None
    total = sum(filter(None, floats))
    if total - total != 0.0 or range_error(floats) is not None:
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
        geom = ewkb_point(lon, lat)
    return make_row(
        m, s, int((t - PG_EPOCH) * 1e6), job, geom, fq, hdop, sraw, sfil, head, cell, trate,
        arate, trpm, arpm, duty, ndvi, depth, down, alarms, backlog, period, stream, *_NO_EXTRAS,
    )  # fmt: skip


assert MAX_FIX_PERIOD_S == 60.0  # the fast path's literal


def _slow_row(d: Any, machine_id: int, now: float, stream: str) -> TelemetryRow | str:
    """Any record: the protocol's own validation, then the column ranges. Row or reason."""
    try:
        rec = TelemetryRecord.from_dict(d)
    except Exception as exc:  # ProtocolError, or TypeError/OverflowError from odd values
        return str(exc) or type(exc).__name__
    if rec.machine_id != machine_id:
        return f"machine_id {rec.machine_id} is not this device's machine ({machine_id})"
    if rec.seq > INT8_MAX:
        return f"seq {rec.seq} out of range"
    if rec.t >= now + FUTURE_TOLERANCE_S:
        return (
            f"t {rec.t!r} is {rec.t - now:.0f} s ahead of the server clock (tolerance"
            f" {FUTURE_TOLERANCE_S:g} s): clock error"
        )
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
        f = [None if v is None else float(v) for v in (getattr(rec, n) for n in FLOAT_FIELDS)]
        period = None if rec.fix_period_s is None else float(rec.fix_period_s)
    except OverflowError:
        return "a number is too large"
    bad = range_error(f)
    if bad is not None:
        return bad
    geom = None
    if rec.lon is not None and rec.lat is not None:
        geom = ewkb_point(float(rec.lon), float(rec.lat))
    return make_row(
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
        period,
        stream,
        *f[11:],
    )


def validate(
    raw: Iterable[Any], machine_id: int, stream: str = "", now: float | None = None
) -> tuple[dict[int, TelemetryRow], list[dict[str, Any]], set[int], int]:
    """Split records into valid rows by seq, rejects, rejected-for-good seqs and in-batch repeats.

    The fast path takes complete, plainly typed records; everything else goes
    through ``TelemetryRecord.from_dict`` (same rules, same messages) and the
    column ranges. ``now``: the server clock (record times beyond it plus
    ``FUTURE_TOLERANCE_S`` are rejected).
    """
    now = time.time() if now is None else now
    t_max = now + FUTURE_TOLERANCE_S
    rows: dict[int, TelemetryRow] = {}
    rejected: list[dict[str, Any]] = []
    dead: set[int] = set()
    repeats = 0
    for d in raw:
        fast = _fast_row(d, machine_id, t_max, stream)
        r = fast if fast is not None else _slow_row(d, machine_id, now, stream)
        if isinstance(r, str):
            seq = d.get("seq") if isinstance(d, dict) else None
            if type(seq) is not int or seq < 1:
                seq = None
            rejected.append({"seq": seq, "reason": r})
            mid = d.get("machine_id") if isinstance(d, dict) else None
            if seq is not None and (mid is None or mid == machine_id):
                dead.add(seq)
            continue
        if r.seq in rows:
            repeats += 1
        else:
            rows[r.seq] = r
    return rows, rejected, dead, repeats


@dataclass
class MachineInfo:
    organisation_id: int
    speed_min_m_s: float
    speed_max_m_s: float
    acked_seq: int | None  # the stream's; None: a stream not seen before
    last_t: float | None
    open_alerts: dict[str, int]  # condition alerts (fleet.alerts.conditions) not ended
    stream_seen: float | None  # this stream's last batch (epoch s)
    other_seen: float | None  # the machine's other streams' last batch (epoch s)
    event_alerts: dict[str, int] = field(default_factory=dict)  # EVENT_KINDS not ended
    # the stream's highest stored seq and first/last record time (int8 us; None: nothing
    # stored): every stored record of the stream lies in that time range (migration 0010)
    max_seq: int | None = None
    first_us: int | None = None
    last_us: int | None = None


LOCK_SQL = "SELECT pg_advisory_xact_lock(%s, %s)"
# every table's machine named as the parameter itself, not only through ``m.id``: past one
# node (Citus) the correlated subqueries otherwise plan as a multi-shard query
_MACHINE_SQL = (
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


def _machine_info(r: Any) -> MachineInfo | None:
    if r is None:
        return None
    alerts = r[5] if isinstance(r[5], dict) else orjson.loads(r[5])
    events = {k: v for k, v in alerts.items() if k in alert_rules.EVENT_KINDS}
    conds = {k: v for k, v in alerts.items() if k not in events}
    return MachineInfo(
        r[0], r[1], r[2], r[3], r[4], conds, r[6], r[7], events, r[8],
        None if r[9] is None else _t_us(r[9]), None if r[10] is None else _t_us(r[10]),
    )  # fmt: skip


def _t_us(t: dt.datetime) -> int:
    """timestamptz -> int8 microseconds since 2000-01-01 (the COPY row's t), exactly."""
    return (t - _PG_EPOCH_DT) // dt.timedelta(microseconds=1)


def ingest(
    conn: psycopg.Connection[Any],
    machine_id: int,
    raw: list[Any],
    stream: str = "",
    stream_start: int = 1,
    streamed: bool | None = None,
) -> IngestResult:
    """Store one batch of ``stream`` for ``machine_id`` (already authenticated); the ack.

    ``stream_start``: the stream's first seq, used when the stream is new.
    ``streamed``: the batch was format 2 (default: a stream was named)."""
    return store_alone(conn, TrackWork.of(machine_id, raw, stream, stream_start, streamed))


class BatchWork(Protocol):
    """What :func:`store_alone` and ``fleet.multibatch`` run: a batch's part of a
    transaction (``TrackWork`` here, ``cellrecords.CellWork`` for cell batches)."""

    machine_id: int
    lock_ns: int
    result: IngestResult

    def prepare(self, conn: psycopg.Connection[Any]) -> None: ...
    def read(self, cur: psycopg.Cursor[Any]) -> None: ...
    def opened(self, row: Any) -> None: ...
    def store(self, cur: psycopg.Cursor[Any]) -> None: ...
    def finish(self, cur: psycopg.Cursor[Any]) -> list[dict[str, Any]]: ...


def store_alone(conn: psycopg.Connection[Any], work: BatchWork) -> IngestResult:
    """Run one batch's work in its own transaction; its ack (true: committed)."""
    work.prepare(conn)
    with pipelined(conn) as cur:
        with conn.pipeline():  # BEGIN travels with the lock query: one round trip
            begin(cur)
            # the lock is its own statement: PostgreSQL takes a statement's snapshot when
            # the statement starts, so a read in the statement that waits for the lock
            # would see the stream as it was before the batch that held the lock committed
            # (a resend stored twice, an ack short of what is stored:
            # tests/fleet/test_ingest_concurrency.py)
            cur.execute(LOCK_SQL, (work.lock_ns, work.machine_id))
            work.read(cur)
            work.opened(cur.fetchone())
        work.store(cur)
        # the rest of the transaction and its COMMIT in one pipeline: the statements whose
        # results are read (ack walk, per-cell progress, alerts) sync it on the way
        with conn.pipeline():
            alert_rules.notify(cur, work.finish(cur))
            commit(cur)
    return work.result


@dataclass
class TrackWork:
    """One telemetry batch's part of a transaction, in the order the caller runs it:
    ``prepare`` (before the transaction), the caller's BEGIN and ``LOCK_SQL`` with
    ``lock_ns``, ``read`` / ``opened`` (after the lock), ``store`` (COPY), ``finish`` (the
    rest; returns the live messages), the caller's NOTIFY and COMMIT. ``result`` is the
    ack, true only once the caller committed. ``ingest`` runs one batch so;
    ``fleet.multibatch`` runs a thin request's track and cell batches in one transaction.
    """

    machine_id: int
    stream: str
    stream_start: int
    now: float
    rows: dict[int, TelemetryRow]
    dead: set[int]
    result: IngestResult
    info: MachineInfo | None = None
    new: list[TelemetryRow] = field(default_factory=list)
    conflict: int | None = None
    lock_ns: int = LOCK_NS

    @classmethod
    def of(
        cls,
        machine_id: int,
        raw: list[Any],
        stream: str = "",
        stream_start: int = 1,
        streamed: bool | None = None,
    ) -> TrackWork:
        """Validate the batch's records (no database)."""
        now = time.time()
        rows, rejected, dead, repeats = validate(raw, machine_id, stream, now)
        result = IngestResult(
            machine_id, stream_start - 1, rejected=rejected, duplicates=repeats, stream=stream,
            streamed=bool(stream) if streamed is None else streamed,
        )  # fmt: skip
        result.flagged = [
            {"seq": q, "reason": FAR_PAST_REASON} for q in sorted(rows) if is_far_past(rows[q].t)
        ]
        return cls(machine_id, stream, stream_start, now, rows, dead, result)

    def prepare(self, conn: psycopg.Connection[Any]) -> None:
        """Make the records' days (own transaction, before the batch's)."""
        ensure_days(conn, [r.t for r in self.rows.values()])

    def read(self, cur: psycopg.Cursor[Any]) -> None:
        """Queue the read of what the batch needs (after the caller's lock statement)."""
        cur.execute(_MACHINE_SQL, {"s": self.stream, "m": self.machine_id})

    def opened(self, row: Any) -> None:
        """The read's row (``read``'s cursor's ``fetchone()``)."""
        info = self.info = _machine_info(row)
        if info is None:
            raise IngestError(f"machine {self.machine_id} does not exist")
        if info.acked_seq is not None:
            self.result.acked_seq = info.acked_seq

    def store(self, cur: psycopg.Cursor[Any]) -> None:
        """Sort out duplicates and a stream conflict; COPY the new rows."""
        self.sort(cur)
        self.copy_all(cur, [self])

    @staticmethod
    def copy_all(cur: psycopg.Cursor[Any], works: Sequence[TrackWork]) -> None:
        """One COPY of the sorted works' new rows (several machines' batches in one
        transaction: ``fleet.multibatch.store_together``)."""
        if any(w.new for w in works):  # COPY cannot be pipelined: two round trips
            TELEMETRY_COPY.write_rows(cur, (r for w in works for r in w.new))

    def sort(self, cur: psycopg.Cursor[Any]) -> None:
        """Sort out duplicates and a stream conflict: ``new``, the rows to COPY."""
        assert self.info is not None
        result, rows, stream = self.result, self.rows, self.stream
        if rows:
            existing = _stored(cur, self.machine_id, stream, self.info, rows)
            if existing:
                same = [q for q, t_us in existing.items() if q in rows and rows[q].t == t_us]
                result.duplicates += len(same)
                clash = [q for q in existing if q in rows and rows[q].t != existing[q]]
                if clash:
                    conflict = self.conflict = min(clash)
                    result.stream_conflict = True
                    for q in sorted(rows):
                        if (q >= conflict and q not in existing) or q in clash:
                            result.rejected.append({"seq": q, "reason": _conflict_reason(
                                q, stream, q in clash)})  # fmt: skip
                    rows = self.rows = {q: r for q, r in rows.items() if q < conflict}
                    self.dead = {q for q in self.dead if q < conflict}
            self.new = [rows[s] for s in sorted(rows) if s not in existing]
        result.stored = len(self.new)

    def finish(self, cur: psycopg.Cursor[Any]) -> list[dict[str, Any]]:
        """Job spans, ack walk, stream row, status, per-cell sums, alerts; the live messages."""
        info, new, result, now = self.info, self.new, self.result, self.now
        machine_id, stream = self.machine_id, self.stream
        assert info is not None
        result.acked_seq = _advance(
            cur, machine_id, stream, result.acked_seq, set(self.rows) | self.dead, info, new
        )
        messages: list[dict[str, Any]] = []
        stream_row = _stream_row(machine_id, stream, self.stream_start, result.acked_seq, new)
        if self.conflict is not None:
            # the agent may trim only below the conflict; it resends the rest on a new stream
            result.acked_seq = min(result.acked_seq, self.conflict - 1)
        # the job spans, the stream's row and the machine's status: one upsert each (as
        # common table expressions of one statement they were not one router plan on Citus,
        # which router-plans no INSERT inside WITH: three subplans through the coordinator)
        spans = job_spans_sql(machine_id, [r.t for r in new], [r.job_id for r in new])
        for part in (spans, stream_row, _status(machine_id, info, new, result.acked_seq, now)):
            if part is not None:
                cur.execute(*part)
        messages.extend(_far_past_alert(cur, machine_id, info, new))
        if not new:
            messages.extend(_streams_alert(cur, machine_id, stream, info, new, now))
            return messages
        latest = max(new, key=lambda r: r.t)
        messages.append(_position(info.organisation_id, latest, result))
        messages.extend(_cells(cur, machine_id, info.organisation_id, new))
        messages.extend(_streams_alert(cur, machine_id, stream, info, new, now))
        if _may_alert(new, info):
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
            from fieldrx.fleet.seed_alerts import check_depth_window

            messages.extend(
                check_depth_window(
                    cur, machine_id, info.organisation_id, latest.job_id, info.open_alerts
                )
            )
        return messages


@contextmanager
def pipelined(conn: psycopg.Connection[Any]) -> Iterator[psycopg.Cursor[Any]]:
    """A cursor for one batch transaction sent in as few round trips as possible.

    ``conn.transaction()`` costs a round trip for BEGIN and one for COMMIT; at a few
    hundred batches per second those and the statements between them (each its own
    round trip: a context switch on both sides) cost more CPU than the rows. Here the
    caller queues ``begin`` with its first statement and ``commit`` with its last ones
    inside ``conn.pipeline()`` blocks (libpq pipeline mode: statements are sent at once,
    results read at the next sync; COPY runs between the blocks). Any error rolls the
    transaction back, so a failed batch leaves nothing, as before."""
    cur = conn.cursor()
    try:
        yield cur
    except BaseException:
        if not conn.closed and conn.info.transaction_status != psycopg.pq.TransactionStatus.IDLE:
            conn.rollback()
        raise
    finally:
        cur.close()
    if conn.info.transaction_status != psycopg.pq.TransactionStatus.IDLE:
        conn.rollback()  # the caller did not commit: leave nothing half done
        raise RuntimeError("a pipelined batch transaction ended without commit")


def begin(cur: psycopg.Cursor[Any]) -> None:
    """BEGIN (an autocommit connection; without autocommit psycopg opens it itself)."""
    if cur.connection.autocommit:
        cur.execute("BEGIN")


def commit(cur: psycopg.Cursor[Any]) -> None:
    cur.execute("COMMIT")


def _ts(us: int) -> dt.datetime:
    return _PG_EPOCH_DT + dt.timedelta(microseconds=us)


def _stored(
    cur: psycopg.Cursor[Any],
    machine_id: int,
    stream: str,
    info: MachineInfo,
    rows: Mapping[int, tuple[Any, ...]],
) -> dict[int, int]:
    """Stored records of the stream holding a seq of this batch: seq -> t (int8 us).

    Only seqs up to the stream's highest stored seq can be stored; a batch above it (new
    records in order, the common case) needs no lookup. A resend holds the same records,
    so its stored copies lie within the batch's own time range: looked up there first
    (one or two days). What is still unmatched (records stored out of order, or another
    record under the same seq: a restored queue) is looked up over the stream's first to
    last record time, which holds every stored record of the stream.
    """
    if info.acked_seq is None or info.max_seq is None:  # a new stream holds nothing yet
        return {}
    cand = [q for q in rows if q <= info.max_seq]
    if not cand:
        return {}
    sql = (
        "SELECT seq, t FROM telemetry WHERE machine_id = %s AND stream = %s"
        " AND seq BETWEEN %s AND %s AND t BETWEEN %s AND %s"
    )
    ts = [rows[q][2] for q in cand]
    cur.execute(sql, (machine_id, stream, min(cand), max(cand), _ts(min(ts)), _ts(max(ts))))
    found = {seq: _t_us(t) for seq, t in cur.fetchall()}
    rest = [q for q in cand if q not in found]
    if rest and info.first_us is not None and info.last_us is not None:
        cur.execute(
            sql,
            (machine_id, stream, min(rest), max(rest), _ts(info.first_us), _ts(info.last_us)),
        )
        found.update((seq, _t_us(t)) for seq, t in cur.fetchall())
    return found


def _conflict_reason(seq: int, stream: str, clash: bool) -> str:
    what = "holds a different record" if clash else "follows a seq that does"
    return (
        f"seq {seq} on stream {stream or '(legacy)'} {what}: this queue's numbering went"
        " backwards (restored or cloned state?); not stored, continue on a new stream"
    )


def _stream_row(
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


def _far_past_alert(
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


def _streams_alert(
    cur: psycopg.Cursor[Any],
    machine_id: int,
    stream: str,
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


def _may_alert(new: list[TelemetryRow], info: MachineInfo) -> bool:
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


def _advance(
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
    t0, t1 = _ts(min(us)), _ts(max(us))

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


def _status(
    machine_id: int,
    info: MachineInfo,
    new: list[TelemetryRow],
    acked: int,
    now: float,
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


def _position(org: int, r: TelemetryRow, result: IngestResult) -> dict[str, Any]:
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


def _cells(
    cur: psycopg.Cursor[Any], machine_id: int, org: int, new: list[TelemetryRow]
) -> list[dict[str, Any]]:
    """Add the batch to the per-cell aggregates of this machine's jobs; update job progress.

    Only records with a job, a cell and the implement down count. When a cell
    counts as done (``jobs.cells_applied``) depends on the job's kind:
    a prescription-map job (seed 001) once the cell has received a positive
    applied rate; a sensor kind (``PROGRESS_BY_WORK``: seed 000 topdressing,
    seed 002 seeding) once the implement has worked in it, i.e. its first
    implement-down record -- a seeding job reports no fertilizer rate at all
    and stayed at 0 %, and a topdressing cell whose sensor said
    "no fertilizer" has still been driven. One statement per batch: both counts
    are taken per job and the job's kind picks one.
    """
    agg: dict[tuple[int, int], list[Any]] = {}  # (job, cell) -> [n, target, applied, t0, t1]
    for r in new:
        if r.job_id is None or r.cell_seq is None or not r.implement_down:
            continue
        key = (r.job_id, r.cell_seq)
        a = agg.get(key)
        tr = r.target_rate_kg_ha or 0.0
        ar = r.applied_rate_kg_ha or 0.0
        if a is None:
            agg[key] = [1, tr, ar, r.t, r.t]
        else:
            a[0] += 1
            a[1] += tr
            a[2] += ar
            if r.t < a[3]:
                a[3] = r.t
            if r.t > a[4]:
                a[4] = r.t
    return cell_progress(cur, machine_id, org, agg)


def cell_progress(
    cur: psycopg.Cursor[Any], machine_id: int, org: int, agg: dict[tuple[int, int], list[Any]]
) -> list[dict[str, Any]]:
    """Add per-cell sums ((job, cell) -> [records, target rate sum, applied rate sum,
    first t, last t], times as COPY microseconds) of this machine's jobs to
    ``job_cells_applied`` and move job progress (``_cells`` for the rules); the job
    messages for the live view. Two statements, each a single-shard router plan on Citus
    (docs/scale.md section 2): Citus router-plans common table expressions that read or
    UPDATE, never one that INSERTs, so the upsert of the sums is its own statement."""
    if not agg:
        return []
    params = cell_progress_params(machine_id, agg)
    # progress first: it reads the cells' rows before this batch's sums are added (the
    # batch's machine is locked, so nothing else writes them in between)
    cur.execute(
        "WITH " + CELL_PROGRESS_CTE + " SELECT id, state, cells_applied, n_cells FROM moved",
        params,
    )
    moved = cur.fetchall()
    cur.execute(CELL_UPSERT_SQL, params)
    return job_messages(machine_id, org, moved)


# ``cell_progress`` as common table expressions (parameters: ``cell_progress_params``); the
# last one, ``moved``, returns the jobs whose progress moved (id, state, cells_applied,
# n_cells): ``job_messages``
CELL_PROGRESS_CTE = """
    new AS (
        -- one JSON parameter, parsed once (arrays are dumped element by element in Python)
        SELECT n.job_id, n.seq, n.n, n.ts, n.aps,
            timestamptz '2000-01-01 00:00:00+00' + n.ft * interval '1 microsecond' AS ft,
            timestamptz '2000-01-01 00:00:00+00' + n.lt * interval '1 microsecond' AS lt
        FROM json_to_recordset(%(cells)s::json)
            AS n(job_id int, seq int, n int, ts float8, aps float8, ft int8, lt int8)
        -- this machine's jobs
        WHERE n.job_id IN (SELECT id FROM jobs WHERE machine_id = %(m)s)
    ), old AS MATERIALIZED (
        -- each new cell's row before this batch's sums (``CELL_UPSERT_SQL`` runs next),
        -- looked up once per new cell; materialised, with ``gained`` reading only this:
        -- inlined into a join with the upsert (the planner estimates one row for both)
        -- it was re-run per upserted cell, n^2 index scans (a 200-cell batch of the thin
        -- profile: 40,401, 45-170 ms; tests/fleet/test_cell_progress_plan.py)
        SELECT n.job_id, n.aps, c.seq IS NOT NULL AS existed,
            coalesce(c.applied_rate_sum, 0) AS before_aps
        FROM new n LEFT JOIN job_cells_applied c
            ON c.machine_id = %(m)s AND c.job_id = n.job_id AND c.seq = n.seq
    ), gained AS (
        -- every new cell is then upserted (inserted, or updated: its sum becomes
        -- before + aps, the same float8 sum as ``CELL_UPSERT_SQL``'s), so the counts
        -- follow from ``old``
        SELECT job_id,
            count(*) FILTER (WHERE NOT existed) AS worked,  -- first record in the cell
            count(*) FILTER (WHERE before_aps + aps > 0 AND before_aps <= 0) AS applied
        FROM old
        GROUP BY job_id
    ), moved AS (
        UPDATE jobs j SET cells_applied = j.cells_applied + g.k, updated_at = now()
        FROM (SELECT g.job_id, CASE WHEN jk.kind = ANY(%(kinds)s::text[]) THEN g.worked
                                    ELSE g.applied END AS k
              FROM gained g JOIN jobs jk ON jk.machine_id = %(m)s AND jk.id = g.job_id) g
        WHERE j.machine_id = %(m)s AND j.id = g.job_id AND g.k > 0
        RETURNING j.id, j.state, j.cells_applied, j.n_cells
    )
"""


# ``cell_progress``'s sums added to ``job_cells_applied``, after ``CELL_PROGRESS_CTE`` read
# the rows before them. The batch's cells join their jobs on this machine: on Citus an
# INSERT ... SELECT that reads a co-located table by its distribution column is pushed down
# to the machine's shard (from the JSON alone it is pulled through the coordinator)
CELL_UPSERT_SQL = """
    INSERT INTO job_cells_applied AS c (machine_id, job_id, seq, n_records,
        target_rate_sum, applied_rate_sum, first_t, last_t)
    SELECT j.machine_id, n.job_id, n.seq, n.n, n.ts, n.aps,
        timestamptz '2000-01-01 00:00:00+00' + n.ft * interval '1 microsecond',
        timestamptz '2000-01-01 00:00:00+00' + n.lt * interval '1 microsecond'
    FROM json_to_recordset(%(cells)s::json)
        AS n(job_id int, seq int, n int, ts float8, aps float8, ft int8, lt int8)
    JOIN jobs j ON j.machine_id = %(m)s AND j.id = n.job_id
    ON CONFLICT (machine_id, job_id, seq) DO UPDATE SET
        n_records = c.n_records + excluded.n_records,
        target_rate_sum = c.target_rate_sum + excluded.target_rate_sum,
        applied_rate_sum = c.applied_rate_sum + excluded.applied_rate_sum,
        first_t = least(c.first_t, excluded.first_t),
        last_t = greatest(c.last_t, excluded.last_t)
"""


def cell_progress_params(machine_id: int, agg: dict[tuple[int, int], list[Any]]) -> dict[str, Any]:
    """``CELL_PROGRESS_CTE``'s parameters for these per-cell sums (``cell_progress``)."""
    return {
        "cells": orjson.dumps(
            [
                {"job_id": j, "seq": c, "n": n, "ts": ts, "aps": aps, "ft": ft, "lt": lt}
                for (j, c), (n, ts, aps, ft, lt) in agg.items()
            ]
        ).decode(),
        "m": machine_id,
        "kinds": list(PROGRESS_BY_WORK),
    }


def job_messages(machine_id: int, org: int, moved: Iterable[Any]) -> list[dict[str, Any]]:
    """Live messages of the jobs whose progress moved (``CELL_PROGRESS_CTE``'s ``moved``)."""
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
