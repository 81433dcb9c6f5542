"""Ingest stage 4, store: one batch transaction in few round trips, and the COPY into it.

A transaction-level advisory lock per machine serialises concurrent batches of the same
machine (two MQTT workers, a retry racing the original, two agents), so the stream's
stored seqs can be read once and the new rows COPied straight into ``telemetry`` with
COPY BINARY (EWKB points), the fastest path measured here (docs/architecture.md, "Stack
notes"). ``telemetry`` is partitioned by day (``fleet.partitions``): the records' days are
made first if missing, in a transaction of their own.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import Any, Protocol

import psycopg

from fieldrx.fleet import alerts as alert_rules
from fieldrx.fleet.ingest.model import IngestResult
from fieldrx.fleet.partitions import ensure_days
from fieldrx.fleet.telemetry_row import TELEMETRY_COPY, TelemetryRow

LOCK_SQL = "SELECT pg_advisory_xact_lock(%s, %s)"


class BatchWork(Protocol):
    """What :func:`store_alone` and ``fleet.multibatch`` run: a batch's part of a
    transaction (``pipeline.TrackWork`` for telemetry, ``cellrecords.CellWork`` for cell
    batches)."""

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
            # tests/fleet/ingest/test_store_concurrency.py)
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


def make_days(conn: psycopg.Connection[Any], rows: Iterable[TelemetryRow]) -> None:
    """Make the rows' day partitions that are missing (own transaction, before the batch's)."""
    ensure_days(conn, [r.t for r in rows])


def copy_rows(cur: psycopg.Cursor[Any], rows: list[TelemetryRow]) -> None:
    """One COPY BINARY of the rows into ``telemetry`` (none: no statement). COPY cannot be
    pipelined: two round trips."""
    if rows:
        TELEMETRY_COPY.write_rows(cur, rows)
