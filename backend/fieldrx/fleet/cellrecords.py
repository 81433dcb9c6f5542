"""Cell records of the thin uplink profile: validate, COPY, deduplicate, acknowledge.

A thin agent (``fieldrx_edge.uplink.thin``) sends its 1 Hz track as ordinary
telemetry (``fleet.ingest``) and, on a stream of their own, one
``cell_records.CellRecord`` per cell it left, in cell batches (format 3,
``"kind": "cells"``). They are stored here, in ``job_cell_records`` (kept
forever, whatever the telemetry retention), with the semantics of the
telemetry ingest (``fleet.ingest``'s stages), so nothing is lost or stored
twice:

1. each record is validated on its own (``CellRecord`` rules, its machine, a
   job of this machine, a time not beyond the server clock's tolerance); a bad
   record is rejected with a reason and, when resending can never help,
   acknowledged past;
2. a transaction-level advisory lock per machine serialises the machine's cell
   batches; the stream's stored seqs are read once and the new rows COPied;
3. a seq already stored is a duplicate if it is the same record (same cell and
   exit time), else the stream's numbering went backwards: nothing from there
   on is stored and the ack says ``stream_conflict``;
4. ``acked_seq`` (``cell_record_streams``) advances over the contiguous stored
   or rejected-for-good seqs and stops at the first gap (``ACK_WALK_SQL``: one
   statement, before the stream row's upsert ``STREAM_ROW_SQL``);
5. per-cell aggregates and job progress move as for telemetry records
   (``ingest.progress.cell_progress``). A thin request's track batch and cell batch
   share one transaction (``fleet.multibatch``).
"""

from __future__ import annotations

import datetime as dt
import operator
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import psycopg
from fieldrx_edge.cell_records import CELL_FIELDS, CellRecord
from fieldrx_edge.protocol import ALARMS, INT4_MAX
from sqlalchemy import text
from sqlalchemy.orm import Session

from fieldrx.fleet.ingest.model import INT8_MAX, IngestError, IngestResult
from fieldrx.fleet.ingest.progress import cell_progress
from fieldrx.fleet.ingest.store import store_alone
from fieldrx.fleet.ingest.validate import FUTURE_TOLERANCE_S
from fieldrx.fleet.telemetry_row import PG_EPOCH

COLUMNS = (
    "machine_id", "stream", "seq", "job_id", "cell_seq", "t_entry", "t_exit", "n_fixes",
    "worked_s", "mass_g", "driven_m", "mean_speed_m_s", "mean_target_rate_kg_ha",
    "mean_applied_rate_kg_ha", "flags",
)  # fmt: skip
COPY_TYPES = (
    "int4", "varchar", "int8", "int4", "int4", "timestamptz", "timestamptz", "int4", "float8",
    "float8", "float8", "float8", "float8", "float8", "varchar[]",
)  # fmt: skip
COPY_SQL = f"COPY job_cell_records ({', '.join(COLUMNS)}) FROM STDIN (FORMAT BINARY)"
LOCK_NS = 7002  # advisory lock namespace: one machine's cell batches, one at a time


def _ts(t: float) -> dt.datetime:
    return dt.datetime.fromtimestamp(t, dt.UTC)


def _us(t: float) -> int:
    """Unix seconds -> microseconds since 2000-01-01 (``ingest.progress.cell_progress``'s times)."""
    return int(round((t - PG_EPOCH) * 1e6))


def validate(
    raw: list[Any], machine_id: int, stream: str, now: float
) -> tuple[dict[int, tuple[Any, ...]], list[dict[str, Any]], set[int], int]:
    """Valid rows by seq, rejects, rejected-for-good seqs and in-batch repeats."""
    rows: dict[int, tuple[Any, ...]] = {}
    rejected: list[dict[str, Any]] = []
    dead: set[int] = set()
    repeats = 0
    t_max = now + FUTURE_TOLERANCE_S
    for d in raw:
        row = _fast_cell(d, machine_id, stream, t_max)
        if row is not None:
            if row[2] in rows:
                repeats += 1
            else:
                rows[row[2]] = row
            continue
        reason = None
        try:
            rec = CellRecord.from_dict(d)
        except Exception as exc:  # ProtocolError, or TypeError from odd values
            reason = str(exc) or type(exc).__name__
        else:
            if rec.machine_id != machine_id:
                reason = f"machine_id {rec.machine_id} is not this device's machine ({machine_id})"
            elif rec.seq > INT8_MAX:
                reason = f"seq {rec.seq} out of range"
            elif rec.t_exit >= now + FUTURE_TOLERANCE_S:
                reason = f"t_exit {rec.t_exit!r} is ahead of the server clock: clock error"
        if reason is not None:
            seq = d.get("seq") if isinstance(d, dict) else None
            seq = seq if type(seq) is int and seq >= 1 else None
            rejected.append({"seq": seq, "reason": reason})
            mid = d.get("machine_id") if isinstance(d, dict) else None
            if seq is not None and (mid is None or mid == machine_id):
                dead.add(seq)
            continue
        if rec.seq in rows:
            repeats += 1
            continue
        rows[rec.seq] = (
            machine_id, stream, rec.seq, rec.job_id, rec.cell_seq, _ts(rec.t_entry),
            _ts(rec.t_exit), rec.n_fixes, float(rec.worked_s), float(rec.mass_g),
            _f(rec.driven_m), _f(rec.mean_speed_m_s), _f(rec.mean_target_rate_kg_ha),
            _f(rec.mean_applied_rate_kg_ha), list(rec.flags),
        )  # fmt: skip
    return rows, rejected, dead, repeats


_CELL_GET = operator.itemgetter(*CELL_FIELDS)
_CELL_KEYS = frozenset(CELL_FIELDS)
_ALARM_SET = frozenset(ALARMS)
_FMAX = sys.float_info.max
assert CELL_FIELDS == (
    "machine_id", "seq", "job_id", "t_entry", "t_exit", "cell_seq", "n_fixes", "worked_s",
    "mass_g", "driven_m", "mean_speed_m_s", "mean_target_rate_kg_ha",
    "mean_applied_rate_kg_ha", "flags",
)  # fmt: skip


def _fast_cell(d: Any, machine_id: int, stream: str, t_max: float) -> tuple[Any, ...] | None:
    """A complete, plainly typed cell record (what agents send) that passes
    ``CellRecord``'s rules -> its COPY row; else None: ``CellRecord.from_dict`` decides
    (same rules, and the reason). A quarter of the cost per record."""
    if type(d) is not dict or len(d) != len(CELL_FIELDS) or not d.keys() <= _CELL_KEYS:
        return None
    (m, seq, job, t0, t1, cell, n, worked, mass, driven, speed, trate, arate,
     flags) = _CELL_GET(d)  # fmt: skip
    if (
        type(m) is not int
        or m != machine_id
        or type(seq) is not int
        or not 1 <= seq <= INT8_MAX
        or type(job) is not int
        or job < 1
        or type(t0) is not float
        or type(t1) is not float
        or not 0.0 < t0 <= t1 < t_max
        or (cell is not None and (type(cell) is not int or not -INT4_MAX <= cell <= INT4_MAX))
        or type(n) is not int
        or not 0 <= n <= INT4_MAX
        or type(flags) is not list
        or (flags and not _ALARM_SET.issuperset(flags))
    ):
        return None
    for v in (worked, mass):
        if type(v) is not float or not 0.0 <= v <= _FMAX:
            return None
    for v in (driven, speed, trate, arate):
        if v is not None and (type(v) is not float or not 0.0 <= v <= _FMAX):
            return None
    return (
        machine_id, stream, seq, job, cell, _ts(t0), _ts(t1), n, worked, mass, driven, speed,
        trate, arate, list(flags),
    )  # fmt: skip


def _f(v: float | None) -> float | None:
    return None if v is None else float(v)


def ingest_cells(
    conn: psycopg.Connection[Any],
    machine_id: int,
    raw: list[Any],
    stream: str,
    stream_start: int = 1,
) -> IngestResult:
    """Store one cell batch of ``stream`` for ``machine_id`` (already authenticated); the ack."""
    return store_alone(conn, CellWork.of(machine_id, raw, stream, stream_start))


@dataclass
class CellWork:
    """One cell batch's part of a transaction, in the order ``ingest.pipeline.TrackWork`` documents
    (``prepare``, the caller's BEGIN and lock on ``lock_ns``, ``read`` / ``opened``,
    ``store``, ``finish``, the caller's NOTIFY and COMMIT); ``result`` is the ack, true
    once the caller committed."""

    machine_id: int
    stream: str
    stream_start: int
    rows: dict[int, tuple[Any, ...]]
    dead: set[int]
    result: IngestResult
    org: int = 0
    acked_db: int | None = None
    new: list[tuple[Any, ...]] = field(default_factory=list)
    conflict: int | None = None
    lock_ns: int = LOCK_NS

    @classmethod
    def of(cls, machine_id: int, raw: list[Any], stream: str, stream_start: int = 1) -> CellWork:
        """Validate the batch's records (no database)."""
        if not stream:
            raise IngestError("a cells batch must name its stream")
        rows, rejected, dead, repeats = validate(raw, machine_id, stream, time.time())
        result = IngestResult(
            machine_id, stream_start - 1, rejected=rejected, duplicates=repeats, stream=stream,
            streamed=True,
        )  # fmt: skip
        return cls(machine_id, stream, stream_start, rows, dead, result)

    def prepare(self, conn: psycopg.Connection[Any]) -> None:
        """Nothing to make before the transaction (``job_cell_records`` is not partitioned)."""

    def read(self, cur: psycopg.Cursor[Any]) -> None:
        """Queue the read of the machine, the stream's ack and which jobs are the machine's."""
        # the subquery names the machine itself (not through m.id): past one node (Citus)
        # that keeps the statement on the machine's shard
        cur.execute(
            "SELECT m.organisation_id, s.acked_seq,"
            " (SELECT coalesce(array_agg(j.id), '{}') FROM jobs j WHERE j.machine_id = %(m)s"
            "  AND j.id = ANY(%(jobs)s))"
            " FROM machines m"
            " LEFT JOIN cell_record_streams s ON s.machine_id = m.id AND s.stream = %(s)s"
            " WHERE m.id = %(m)s",
            {"jobs": list({r[3] for r in self.rows.values()}), "s": self.stream,
             "m": self.machine_id},
        )  # fmt: skip

    def opened(self, info: Any) -> None:
        """The read's row; records of another machine's job are rejected for good."""
        if info is None:
            raise IngestError(f"machine {self.machine_id} does not exist")
        self.org, self.acked_db, mine = info[0], info[1], set(info[2])
        rows = self.rows
        for q in [q for q, r in rows.items() if r[3] not in mine]:
            self.result.rejected.append(
                {"seq": q, "reason": f"job {rows[q][3]} is not this machine's job"}
            )
            self.dead.add(q)
            del rows[q]
        if self.acked_db is not None:
            self.result.acked_seq = self.acked_db

    def store(self, cur: psycopg.Cursor[Any]) -> None:
        """Sort out duplicates and a stream conflict; COPY the new rows."""
        self.sort(cur)
        self.copy_all(cur, [self])

    @staticmethod
    def copy_all(cur: psycopg.Cursor[Any], works: Sequence[CellWork]) -> None:
        """One COPY of the sorted works' new rows (``ingest.pipeline.TrackWork.copy_all``)."""
        if any(w.new for w in works):
            with cur.copy(COPY_SQL) as copy:
                copy.set_types(COPY_TYPES)
                for w in works:
                    for r in w.new:
                        copy.write_row(r)

    def sort(self, cur: psycopg.Cursor[Any]) -> None:
        """Sort out duplicates and a stream conflict: ``new``, the rows to COPY."""
        rows, result, stream = self.rows, self.result, self.stream
        if rows:
            existing: dict[int, tuple[Any, ...]] = {}
            if self.acked_db is not None:  # a new stream holds nothing yet
                cur.execute(
                    "SELECT seq, cell_seq, t_exit FROM job_cell_records WHERE machine_id = %s"
                    " AND stream = %s AND seq BETWEEN %s AND %s",
                    (self.machine_id, stream, min(rows), max(rows)),
                )
                existing = {q: (c, t) for q, c, t in cur.fetchall()}
            same = [q for q, k in existing.items() if q in rows and (rows[q][4], rows[q][6]) == k]
            result.duplicates += len(same)
            clash = [q for q in existing if q in rows and q not in same]
            if clash:
                conflict = self.conflict = min(clash)
                result.stream_conflict = True
                for q in sorted(rows):
                    if (q >= conflict and q not in existing) or q in clash:
                        result.rejected.append(
                            {
                                "seq": q,
                                "reason": f"seq {q} on cell stream {stream} holds (or follows)"
                                " a different record: continue on a new stream",
                            }
                        )
                rows = self.rows = {q: r for q, r in rows.items() if q < conflict}
                self.dead = {q for q in self.dead if q < conflict}
            self.new = [rows[q] for q in sorted(rows) if q not in existing]
        result.stored = len(self.new)

    def finish(self, cur: psycopg.Cursor[Any]) -> list[dict[str, Any]]:
        """The stream's row with its ack walk (``ACK_WALK_SQL``), then the per-cell sums and
        job progress (``ingest.progress.cell_progress``); the live messages. Each statement is a
        single-shard router plan on Citus, which refuses a subquery inside INSERT ...
        VALUES and router-plans no INSERT inside a common table expression."""
        done = _int_array(set(self.rows) | self.dead)
        p = {"m": self.machine_id, "s": self.stream, "acked": self.result.acked_seq}
        row = cur.execute("SELECT " + ACK_WALK_SQL, {**p, "done": done}).fetchone()
        assert row is not None
        stream = {"a": row[0], "start": self.stream_start, "nrec": len(self.new)}
        cur.execute(STREAM_ROW_SQL, {**p, **stream})
        self.result.acked_seq = int(row[0])
        if self.conflict is not None:
            self.result.acked_seq = min(self.result.acked_seq, self.conflict - 1)
        return cell_progress(cur, self.machine_id, self.org, _per_cell(self.new))


def _int_array(values: set[int]) -> str:
    """An int8[] parameter as its text (psycopg dumps a list element by element)."""
    return "{" + ",".join(map(str, sorted(values))) + "}"


def _per_cell(new: list[tuple[Any, ...]]) -> dict[tuple[int, int], list[Any]]:
    """New cell records summed per (job, cell) as ``ingest.progress.cell_progress`` takes
    them: fixes, target and applied rate sums over the fixes, first and last time (COPY us)."""
    agg: dict[tuple[int, int], list[Any]] = {}
    for r in new:
        n = r[7]
        if r[4] is None or n == 0:
            continue
        t0, t1 = _us(r[5].timestamp()), _us(r[6].timestamp())
        a = agg.get((r[3], r[4]))
        tsum, asum = (r[12] or 0.0) * n, (r[13] or 0.0) * n
        if a is None:
            agg[(r[3], r[4])] = [n, tsum, asum, t0, t1]
        else:
            a[0] += n
            a[1] += tsum
            a[2] += asum
            a[3], a[4] = min(a[3], t0), max(a[4], t1)
    return agg


# The ack walk in one statement (``ingest.stream.advance_over_stored``'s rule): from the stored
# ack, over the contiguous seqs that are stored on the stream or done in this batch (stored
# or rejected for good), to the first gap. Numbered in seq order, a seq is in the run from
# ack + 1 exactly when it equals ack + its rank; the run is the count of those. At most
# 100,000 stored seqs are read per batch: a longer run is walked on by the next batches
# (an ack below what is stored only makes the agent resend, which is deduplicated).
ACK_WALK_SQL = (
    "(SELECT %(acked)s::int8 + count(*) FROM ("
    " SELECT q, row_number() OVER (ORDER BY q) AS k FROM ("
    "  SELECT seq AS q FROM job_cell_records WHERE machine_id = %(m)s AND stream = %(s)s::text"
    "   AND seq > %(acked)s AND seq <= %(acked)s::int8 + 100000"
    "  UNION SELECT d FROM unnest(%(done)s::int8[]) AS d WHERE d > %(acked)s) u) r"
    " WHERE q = %(acked)s::int8 + k)"
)

# ``CellWork.finish``: the stream's row, its ack walked by ``ACK_WALK_SQL``
STREAM_ROW_SQL = (
    "INSERT INTO cell_record_streams AS s (machine_id, stream, first_seq, acked_seq, n_records)"
    " VALUES (%(m)s, %(s)s::text, %(start)s, %(a)s, %(nrec)s)"
    " ON CONFLICT (machine_id, stream) DO UPDATE"
    " SET acked_seq = excluded.acked_seq, last_seen_at = excluded.last_seen_at,"
    " n_records = s.n_records + excluded.n_records"
)


def job_cell_totals(session: Session, job_id: int, machine_id: int) -> list[Any]:
    """A thin job's cell records summed per cell (null: no cell):
    (cell_seq, fixes, worked s, mass g, target rate sum, applied rate sum, first t, last t),
    the rate sums over fixes and the times (unix s) over cells' own fixes."""
    return list(
        session.execute(
            text(
                "SELECT cell_seq, sum(n_fixes)::int, sum(worked_s), sum(mass_g),"
                " sum(coalesce(mean_target_rate_kg_ha, 0) * n_fixes),"
                " sum(coalesce(mean_applied_rate_kg_ha, 0) * n_fixes),"
                " extract(epoch FROM min(t_entry) FILTER (WHERE n_fixes > 0))::float8,"
                " extract(epoch FROM max(t_exit) FILTER (WHERE n_fixes > 0))::float8"
                " FROM job_cell_records WHERE job_id = :j AND machine_id = :m GROUP BY cell_seq"
            ),
            {"j": job_id, "m": machine_id},
        ).all()
    )
