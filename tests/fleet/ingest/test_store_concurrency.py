"""Two batches of one machine's stream waiting on its ingest lock at once (two MQTT
workers, or two lanes of one) must each see what the other committed.

The lock was taken inside the statement that also read the stream's state; PostgreSQL
(READ COMMITTED) takes a statement's snapshot when it starts, i.e. before the lock wait,
so the second batch read the stream as it was before the first committed: a resend was
stored twice, and a lower batch that followed a higher one acked only itself (the agent's
last ack never came). Real PostgreSQL, real ``fleet.ingest``; the waiters are lined up on
the lock (``pg_locks``) so the order is fixed.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import psycopg
import pytest
from fieldrx.db.session import raw_dsn
from fieldrx.fleet.db import connect
from fieldrx.fleet.ingest.model import IngestResult
from fieldrx.fleet.ingest.pipeline import LOCK_NS, ingest

from tests.fleet.helpers import JobFixture, record
from tests.support import scaled


def _waiters(conn: psycopg.Connection[Any], machine_id: int) -> int:
    return conn.execute(
        "SELECT count(*) FROM pg_locks WHERE locktype = 'advisory' AND NOT granted"
        " AND classid = %s AND objid = %s",
        (LOCK_NS, machine_id),
    ).fetchone()[0]


def _lined_up(
    database_url: str, job: JobFixture, batches: list[list[dict[str, Any]]]
) -> list[IngestResult]:
    """Hold the machine's lock, queue ``batches`` on it in order, then let them run."""
    dsn = raw_dsn(database_url)
    results: list[IngestResult | BaseException] = [RuntimeError("not run")] * len(batches)
    with psycopg.connect(dsn, autocommit=True) as holder, psycopg.connect(dsn) as probe:
        probe.autocommit = True
        holder.execute("BEGIN")
        holder.execute("SELECT pg_advisory_xact_lock(%s, %s)", (LOCK_NS, job.machine_id))
        threads = []
        for i, batch in enumerate(batches):

            def run(i: int = i, batch: list[dict[str, Any]] = batch) -> None:
                with connect(dsn) as c:
                    try:
                        results[i] = ingest(c, job.machine_id, batch, "s", 1, True)
                    except BaseException as exc:  # noqa: BLE001 - reported below
                        results[i] = exc

            t = threading.Thread(target=run)
            t.start()
            threads.append(t)
            deadline = time.monotonic() + scaled(20)
            while _waiters(probe, job.machine_id) < i + 1:
                assert time.monotonic() < deadline, "batch did not reach the lock"
                time.sleep(0.02)
        holder.execute("COMMIT")
        for t in threads:
            t.join(30)
    for r in results:
        if isinstance(r, BaseException):
            raise r
    return results  # type: ignore[return-value]


def _rows(database_url: str, machine_id: int) -> int:
    with psycopg.connect(raw_dsn(database_url)) as c:
        return c.execute(
            "SELECT count(*) FROM telemetry WHERE machine_id = %s AND stream = 's'",
            (machine_id,),
        ).fetchone()[0]


@pytest.mark.parametrize("n", [10])
def test_a_resend_waiting_on_the_lock_is_not_stored_twice(
    database_url: str, job: JobFixture, n: int
) -> None:
    batch = [record(job, s, t=time.time() - 60 + s * 0.1, cell=s % 8) for s in range(1, n + 1)]
    first, again = _lined_up(database_url, job, [batch, batch])
    assert first.stored == n and again.stored == 0 and again.duplicates == n
    assert _rows(database_url, job.machine_id) == n
    assert again.acked_seq == n


def test_a_lower_batch_after_a_higher_one_acks_both(database_url: str, job: JobFixture) -> None:
    t0 = time.time() - 60
    low = [record(job, s, t=t0 + s * 0.1, cell=s % 8) for s in range(1, 11)]
    high = [record(job, s, t=t0 + s * 0.1, cell=s % 8) for s in range(11, 21)]
    r_high, r_low = _lined_up(database_url, job, [high, low])
    assert r_high.acked_seq == 0 and r_high.stored == 10
    assert r_low.stored == 10 and r_low.acked_seq == 20  # walked over the higher batch
    assert _rows(database_url, job.machine_id) == 20
