"""Several batches of one machine in one request (``protocol.MULTI_KIND``), in one transaction.

A thin agent (uplink profile ``thin``) sends its 1 Hz track batch and its cell batch in
one HTTP request. Stored one transaction each (``ingest.pipeline.ingest``, then
``cellrecords.ingest_cells``) that is two BEGIN / lock / read / NOTIFY / COMMIT rounds per
request; here a track batch and a cell batch share one transaction: both locks in one
statement, both reads in one round trip, one NOTIFY, one COMMIT (the thin
profile's server CPU per machine-hour).

An ack is true only once its batch is durably stored, and one batch must not take
another down with it: if the shared transaction fails (a batch the database refuses,
``IngestError``), nothing of it was committed and no ack was sent, so every batch is
stored again on its own, as before. A batch that fails alone then gets an error ack
naming the batch, its stream and the database's reason (``error``; ``acked_seq`` 0 and
nothing rejected: the agent trims nothing of that queue and resends it), and the other
batches are stored and acknowledged as usual. A request with other batches than one
track and one cell batch (``MAX_BATCHES`` allows more) is stored one transaction per
batch.
"""

from __future__ import annotations

import logging
import re
from typing import Any

import orjson
import psycopg

from fieldrx.fleet import alerts as alert_rules
from fieldrx.fleet.cellrecords import CellWork, ingest_cells
from fieldrx.fleet.ingest.model import Batch, IngestError, IngestResult
from fieldrx.fleet.ingest.pipeline import TrackWork, ingest
from fieldrx.fleet.ingest.store import begin, commit, pipelined

log = logging.getLogger(__name__)


def ingest_batches(
    conn: psycopg.Connection[Any], machine_id: int, batches: list[Batch]
) -> list[bytes]:
    """Store a request's batches for ``machine_id`` (already authenticated); one ack (JSON)
    per batch, in order."""
    kinds = [b.kind for b in batches]
    if len(batches) == 2 and sorted(kinds) == ["cells", "telemetry"]:
        try:
            results = _together(conn, machine_id, batches)
        except (IngestError, psycopg.Error) as exc:
            if conn.closed or conn.broken:
                raise
            log.info("machine %s: batches stored one by one (%s)", machine_id, reason_of(exc))
        else:
            return [r.to_json() for r in results]
    return [_alone(conn, machine_id, i, b) for i, b in enumerate(batches)]


def store(conn: psycopg.Connection[Any], machine_id: int, batch: Batch) -> IngestResult:
    """One batch in its own transaction (the single-batch request's path too)."""
    if batch.kind == "cells":  # uplink profile thin: its cell records
        return ingest_cells(conn, machine_id, batch.records, batch.stream, batch.stream_start)
    return ingest(conn, machine_id, batch.records, batch.stream, batch.stream_start, batch.streamed)


def _together(
    conn: psycopg.Connection[Any], machine_id: int, batches: list[Batch]
) -> list[IngestResult]:
    """A track and a cell batch in one transaction; their acks, once it committed."""
    return store_together(conn, [work_of(machine_id, b) for b in batches])


Work = TrackWork | CellWork


def work_of(machine_id: int, batch: Batch) -> Work:
    """The batch's part of a transaction (its records validated: no database)."""
    if batch.kind == "cells":
        return CellWork.of(machine_id, batch.records, batch.stream, batch.stream_start)
    return TrackWork.of(machine_id, batch.records, batch.stream, batch.stream_start, batch.streamed)


def store_together(conn: psycopg.Connection[Any], works: list[Work]) -> list[IngestResult]:
    """Several batches, of one machine or of several, in one transaction; their acks (true
    once this returns: it committed). Any error rolls all of them back (``pipelined``).

    One statement takes every lock, ordered by (machine, lock namespace): a select list is
    evaluated left to right, and every caller takes its locks in that order (a lone batch
    takes one), so two such transactions cannot deadlock. The caller gives at most one
    work per (machine, lock namespace): each work reads its machine's state after the
    locks, before any work of the transaction writes, so a second batch of the same
    machine and kind would read what the first is about to change (``fleet.worker`` keeps
    it for its next transaction). The reads follow the lock statement in the same round
    trip (their snapshot after the wait), then one COPY per table, every work's finishing
    statements, one NOTIFY and the COMMIT in one pipeline."""
    results = _store(conn, works, wait=True)
    return [r for r in results if r is not None]


def store_free(conn: psycopg.Connection[Any], works: list[Work]) -> list[IngestResult | None]:
    """``store_together`` for the works whose machines no other transaction holds; None for
    the others (not stored: the caller stores them after this). A transaction of many
    machines that waited for each lock would wait for every other worker's transaction
    holding one of them (shared subscriptions spread a machine's messages over the
    workers), and with it every machine it holds: the workers would take turns."""
    return _store(conn, works, wait=False)


def _store(
    conn: psycopg.Connection[Any], works: list[Work], wait: bool
) -> list[IngestResult | None]:
    for w in works:
        w.prepare(conn)
    locks = sorted({(w.machine_id, w.lock_ns) for w in works})
    if len(locks) != len(works):
        raise ValueError("two batches of one machine and kind in one transaction")
    fn = "pg_advisory_xact_lock" if wait else "pg_try_advisory_xact_lock"
    with pipelined(conn) as cur:
        cursors = [conn.cursor() for _ in works]
        try:
            with conn.pipeline():  # BEGIN, the locks and every read: one round trip
                begin(cur)
                cur.execute(
                    "SELECT " + ", ".join([f"{fn}(%s, %s)"] * len(locks)),
                    [x for m, ns in locks for x in (ns, m)],
                )
                for w, c in zip(works, cursors, strict=True):
                    w.read(c)
                got = cur.fetchone()
                rows = [c.fetchone() for c in cursors]
        finally:
            for c in cursors:
                c.close()
        held = dict(zip(locks, [True] * len(locks) if wait else got or (), strict=True))
        mine = [held[(w.machine_id, w.lock_ns)] for w in works]
        done = [w for w, h in zip(works, mine, strict=True) if h]
        for w, row, h in zip(works, rows, mine, strict=True):
            if h:  # a read without its lock is not used
                w.opened(row)
        for w in done:
            w.sort(cur)
        # one COPY per table for all the works' rows (COPY is outside the pipeline)
        TrackWork.copy_all(cur, [w for w in done if isinstance(w, TrackWork)])
        CellWork.copy_all(cur, [w for w in done if isinstance(w, CellWork)])
        with conn.pipeline():
            messages = [m for w in done for m in w.finish(cur)]
            alert_rules.notify(cur, messages)
            commit(cur)
    return [w.result if h else None for w, h in zip(works, mine, strict=True)]


def _alone(conn: psycopg.Connection[Any], machine_id: int, i: int, batch: Batch) -> bytes:
    """One batch in its own transaction; a batch that fails gets an error ack."""
    try:
        return store(conn, machine_id, batch).to_json()
    except (IngestError, psycopg.Error) as exc:
        if conn.closed or conn.broken:
            raise
        what = f"batches[{i}] ({batch.kind}, stream {batch.stream or '(legacy)'})"
        log.warning("machine %s: %s not stored: %s", machine_id, what, reason_of(exc))
        return error_ack(machine_id, batch, what, exc)


def error_ack(machine_id: int, batch: Batch, what: str, exc: Exception) -> bytes:
    """The ack of a batch that was not stored: ``acked_seq`` 0, nothing rejected (the agent
    trims nothing of that queue and resends it) and ``error`` naming ``what`` and why."""
    reason = f"{what} not stored: {reason_of(exc)}"
    ack = IngestResult(machine_id, 0, stream=batch.stream, streamed=True).to_json()
    return ack[:-1] + b',"error":' + orjson.dumps(reason) + b"}"


# Past one node Citus relays a worker's refusal inside a COPY as an internal error (SQLSTATE
# XX000) that keeps only the worker's message, so the class alone does not say "refused"
_REFUSED_TEXT = re.compile(
    r"violates (check|not-null|foreign key|unique|exclusion) constraint"
    r"|invalid input|out of range|value too long"
)


def refused(exc: psycopg.Error) -> bool:
    """Whether the database refused the data (a constraint, a value it cannot take), as
    opposed to failing: a refused batch gets an error ack, a failure is retried."""
    if isinstance(exc, psycopg.errors.DataError | psycopg.errors.IntegrityError):
        return True
    return isinstance(exc, psycopg.errors.InternalError_) and bool(
        _REFUSED_TEXT.search(exc.diag.message_primary or str(exc))
    )


def reason_of(exc: Exception) -> str:
    """The error's text; for the database's, its detail and where (e.g. the COPY line:
    the record's place in the batch, from 1; in a shared COPY, its place in all of them)."""
    if not isinstance(exc, psycopg.Error):
        return str(exc)
    d = exc.diag
    parts = [d.message_primary or str(exc), d.message_detail, d.context]
    return "; ".join(p.strip() for p in parts if p)
