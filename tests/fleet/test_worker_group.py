"""The MQTT worker stores a round's batches of several machines in one transaction
(``multibatch.store_together``) and acks them only after its commit; a batch the
database refuses takes no other machine's batch down and holds up nobody (it gets an error
ack naming it; before, it was retried forever on the lane). Real PostgreSQL and the real
``IngestWorker._process``; the MQTT client is a recorder (the broker is not contacted:
``IngestWorker`` connects only in ``run``)."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from types import SimpleNamespace
from typing import Any

import psycopg
import pytest
from fieldrx.db.session import raw_dsn
from fieldrx.fleet.db import connect
from fieldrx.fleet.ingest.parse import parse_batch
from fieldrx.fleet.multibatch import store_together, work_of
from fieldrx.fleet.worker import IngestOptions, IngestWorker, WorkerStats, _rounds
from fieldrx_edge.protocol import ack_topic, telemetry_topic

from tests.fleet.helpers import JobFixture, make_job, on_citus, record


class Recorder:
    """The MQTT client's calls the worker makes after a round, in order."""

    def __init__(self) -> None:
        self.calls: list[tuple[Any, ...]] = []
        self.probe: Callable[[], int] | None = None  # e.g. rows committed at each call
        self.seen: list[int] = []

    def publish(self, topic: str, payload: bytes, qos: int = 0) -> None:
        self.calls.append(("publish", topic, json.loads(payload)))
        self._probe()

    def ack(self, mid: int, qos: int) -> None:
        self.calls.append(("puback", mid))
        self._probe()

    def _probe(self) -> None:
        if self.probe is not None:
            self.seen.append(self.probe())

    def acks(self, machine_id: int) -> list[dict[str, Any]]:
        return [c[2] for c in self.calls if c[0] == "publish" and c[1] == ack_topic(machine_id)]


@pytest.fixture()
def worker() -> IngestWorker:
    w = IngestWorker(
        "mqtt://127.0.0.1:1", dsn="postgresql:///unused", opts=IngestOptions(client_id="t")
    )
    w.client = Recorder()  # type: ignore[assignment]
    return w


@pytest.fixture()
def conn(database_url: str) -> Iterator[psycopg.Connection[Any]]:
    with connect(raw_dsn(database_url)) as c:
        yield c


def _msg(mid: int, job: JobFixture, stream: str, seqs: range, t0: float, **kw: Any) -> Any:
    body = {
        "format": 2, "stream": stream, "stream_start": 1,
        "records": [record(job, q, t=t0 + q, cell=None, **kw) for q in seqs],
    }  # fmt: skip
    return SimpleNamespace(
        topic=telemetry_topic(job.machine_id), payload=json.dumps(body).encode(), mid=mid, qos=1
    )


def _xmins(conn: psycopg.Connection[Any], machine_id: int, stream: str) -> set[str]:
    rows = conn.execute(
        "SELECT DISTINCT xmin::text FROM telemetry WHERE machine_id = %s AND stream = %s",
        (machine_id, stream),
    ).fetchall()
    return {r[0] for r in rows}


def _pubacks(w: IngestWorker) -> list[int]:
    return sorted(c[1] for c in w.client.calls if c[0] == "puback")  # type: ignore[attr-defined]


def test_several_machines_batches_share_one_transaction(worker, conn, org, database_url) -> None:  # noqa: ANN001, E501
    jobs = [make_job(org.id, state="running") for _ in range(3)]
    t0 = time.time() - 100
    msgs = [_msg(i + 1, j, "s", range(1, 6), t0) for i, j in enumerate(jobs)]
    stats = WorkerStats()
    rec: Recorder = worker.client  # type: ignore[assignment]
    with psycopg.connect(raw_dsn(database_url), autocommit=True) as other:
        ids = [j.machine_id for j in jobs]
        rec.probe = lambda: other.execute(
            "SELECT count(*) FROM telemetry WHERE machine_id = ANY(%s)", (ids,)
        ).fetchone()[0]
        worker._process(conn, msgs, stats)
    # every ack and PUBACK went after the one commit that made all 15 rows visible
    assert rec.seen == [15] * 6
    xmins = set().union(*(_xmins(conn, j.machine_id, "s") for j in jobs))
    # one transaction stored the three machines' batches (on Citus each shard's part has
    # its node's own transaction id: each machine's rows one, the commit visible at once)
    if on_citus(conn):
        assert all(len(_xmins(conn, j.machine_id, "s")) == 1 for j in jobs)
    else:
        assert len(xmins) == 1, xmins
    for j in jobs:
        (a,) = rec.acks(j.machine_id)
        assert (a["stream"], a["acked_seq"], a["stored"], "error" in a) == ("s", 5, 5, False)
    assert _pubacks(worker) == [1, 2, 3]
    assert (stats.batches, stats.stored, stats.errors) == (3, 15, 0)


def test_a_refused_batch_takes_no_other_machine_down(worker, conn, org, db) -> None:  # noqa: ANN001
    from sqlalchemy import text

    a, b, c = (make_job(org.id, state="running") for _ in range(3))
    t0 = time.time() - 100
    db.execute(text(  # only machine b's rows: the session's other tests store any duty
        f"ALTER TABLE telemetry ADD CONSTRAINT test_duty CHECK (machine_id <> {b.machine_id}"
        " OR duty < 99)"
    ))  # fmt: skip
    db.commit()
    try:
        bad = _msg(2, b, "s", range(1, 4), t0)
        body = json.loads(bad.payload)
        body["records"][1]["duty"] = 99.5  # the protocol allows it, the constraint does not
        bad.payload = json.dumps(body).encode()
        msgs = [_msg(1, a, "s", range(1, 6), t0), bad, _msg(3, c, "s", range(1, 4), t0)]
        worker._process(conn, msgs, WorkerStats())  # before: retried machine b forever
    finally:
        db.execute(text("ALTER TABLE telemetry DROP CONSTRAINT test_duty"))
        db.commit()
    rec: Recorder = worker.client  # type: ignore[assignment]
    (aa,) = rec.acks(a.machine_id)
    (cc,) = rec.acks(c.machine_id)
    assert (aa["acked_seq"], aa["stored"], cc["acked_seq"], cc["stored"]) == (5, 5, 3, 3)
    (bb,) = rec.acks(b.machine_id)
    assert (bb["stream"], bb["acked_seq"], bb["stored"]) == ("s", 0, 0)
    assert "test_duty" in bb["error"], bb["error"]
    # the COPY line of the refused record (Citus relays the worker's message without it)
    assert "line 2" in bb["error"] or on_citus(conn), bb["error"]
    assert _pubacks(worker) == [1, 2, 3]  # each message once: none left to redeliver
    assert _xmins(conn, b.machine_id, "s") == set()  # the batch is all or nothing
    n = conn.execute(
        "SELECT count(*) FROM telemetry WHERE machine_id = ANY(%s)", ([a.machine_id, c.machine_id],)
    ).fetchone()
    assert n is not None and n[0] == 8  # stored once each, not again by the retry alone
    # the agent resends b's batch (nothing was trimmed): stored now, once
    worker._process(conn, [bad], WorkerStats())
    assert (rec.acks(b.machine_id)[-1]["acked_seq"], rec.acks(b.machine_id)[-1]["stored"]) == (3, 3)


def test_same_machine_twice_in_a_round(worker, conn, org) -> None:  # noqa: ANN001
    a, b = make_job(org.id, state="running"), make_job(org.id, state="running")
    t0 = time.time() - 100
    msgs = [
        _msg(1, a, "s1", range(1, 4), t0),
        _msg(2, a, "s1", range(4, 7), t0),  # same stream: one batch with the first
        _msg(3, a, "s2", range(1, 3), t0 + 10),  # the machine's other stream: next transaction
        _msg(4, b, "s1", range(1, 3), t0),
    ]
    worker._process(conn, msgs, WorkerStats())
    rec: Recorder = worker.client  # type: ignore[assignment]
    assert [(x["stream"], x["acked_seq"], x["stored"]) for x in rec.acks(a.machine_id)] == [
        ("s1", 6, 6),
        ("s2", 2, 2),
    ]
    first, second = _xmins(conn, a.machine_id, "s1"), _xmins(conn, a.machine_id, "s2")
    assert len(first) == 1
    assert on_citus(conn) or first == _xmins(conn, b.machine_id, "s1")  # Citus: per node
    assert len(second) == 1 and second != first
    assert _pubacks(worker) == [1, 2, 3, 4]


def test_rounds_keep_one_batch_per_machine_and_kind_in_order() -> None:
    def entry(m: int, stream: str, kind: str = "telemetry") -> Any:
        return ((m, stream), (SimpleNamespace(kind=kind), []))

    es = [entry(1, "a"), entry(2, "a"), entry(1, "b"), entry(1, "c", "cells"), entry(1, "d")]
    got = [[(e[0][0], e[0][1]) for e in r] for r in _rounds(es)]
    assert got == [[(1, "a"), (2, "a"), (1, "c")], [(1, "b")], [(1, "d")]]


def test_two_batches_of_one_machine_and_kind_are_refused(conn, org) -> None:  # noqa: ANN001
    j = make_job(org.id, state="running")
    t0 = time.time() - 100
    works = [work_of(j.machine_id, parse_batch(_msg(1, j, s, range(1, 3), t0).payload))
             for s in ("x", "y")]  # fmt: skip
    with pytest.raises(ValueError, match="two batches of one machine and kind"):
        store_together(conn, works)


def test_a_busy_machine_is_left_for_later_not_waited_for(conn, org, database_url) -> None:  # noqa: ANN001
    """``store_free`` stores the machines no other transaction holds and leaves the others
    (None): a many-machine transaction that waited for one lock would hold all its other
    machines for as long (two workers took turns instead of working at once)."""
    from fieldrx.fleet.ingest.pipeline import LOCK_NS
    from fieldrx.fleet.multibatch import store_free

    a, b = make_job(org.id, state="running"), make_job(org.id, state="running")
    t0 = time.time() - 100
    works = [work_of(j.machine_id, parse_batch(_msg(1, j, "s", range(1, 4), t0).payload))
             for j in (a, b)]  # fmt: skip
    with psycopg.connect(raw_dsn(database_url), autocommit=True) as holder:
        holder.execute("BEGIN")
        holder.execute("SELECT pg_advisory_xact_lock(%s, %s)", (LOCK_NS, b.machine_id))
        ra, rb = store_free(conn, works)  # returns at once, b's lock still held
        holder.execute("COMMIT")
    assert ra is not None and (ra.acked_seq, ra.stored) == (3, 3)
    assert rb is None and _xmins(conn, b.machine_id, "s") == set()
    (rb,) = store_together(
        conn, [work_of(b.machine_id, parse_batch(_msg(1, b, "s", range(1, 4), t0).payload))]
    )
    assert (rb.acked_seq, rb.stored) == (3, 3)


def test_a_busy_machines_batch_is_held_over_once(worker, conn, org, database_url) -> None:  # noqa: ANN001
    """In the lane, a batch whose machine another transaction holds waits for the next
    round (unacked, nothing stored), the others are stored and acked at once; held over
    again, it is waited for."""
    from fieldrx.fleet.ingest.pipeline import LOCK_NS

    a, b = make_job(org.id, state="running"), make_job(org.id, state="running")
    t0 = time.time() - 100
    msgs = [_msg(1, a, "s", range(1, 4), t0), _msg(2, b, "s", range(1, 4), t0)]
    held: dict[Any, Any] = {}
    rec: Recorder = worker.client  # type: ignore[assignment]
    with psycopg.connect(raw_dsn(database_url), autocommit=True) as holder:
        holder.execute("BEGIN")
        holder.execute("SELECT pg_advisory_xact_lock(%s, %s)", (LOCK_NS, b.machine_id))
        worker._process(conn, msgs, WorkerStats(), held)
        holder.execute("COMMIT")
    assert list(held) == [(b.machine_id, "s")]
    assert _pubacks(worker) == [1] and rec.acks(b.machine_id) == []
    assert _xmins(conn, b.machine_id, "s") == set()
    worker._process(conn, [_msg(3, b, "s", range(4, 6), t0)], WorkerStats(), held)
    assert held == {}
    assert [(x["acked_seq"], x["stored"]) for x in rec.acks(b.machine_id)] == [(5, 5)]
    assert _pubacks(worker) == [1, 2, 3]


def test_a_batch_of_a_deleted_machine_gets_an_error_ack(worker, conn, org, db) -> None:  # noqa: ANN001
    """A machine deleted while its messages were in flight: its batch was PUBACKed with no
    ack at all (the agent waited out its ack timeout and resent it, nothing said why). It
    gets an error ack naming the reason, and the other machines' batches are stored."""
    from sqlalchemy import text

    a, b = (make_job(org.id, state="running") for _ in range(2))
    t0 = time.time() - 100
    msgs = [_msg(1, a, "s", range(1, 4), t0), _msg(2, b, "s", range(1, 4), t0)]
    db.execute(text("DELETE FROM machines WHERE id = :m"), {"m": b.machine_id})
    db.commit()
    stats = WorkerStats()
    worker._process(conn, msgs, stats)
    rec: Recorder = worker.client  # type: ignore[assignment]
    (aa,) = rec.acks(a.machine_id)
    assert (aa["acked_seq"], aa["stored"], "error" in aa) == (3, 3, False)
    (bb,) = rec.acks(b.machine_id)
    assert (bb["stream"], bb["acked_seq"], bb["stored"]) == ("s", 0, 0)
    assert f"machine {b.machine_id} does not exist" in bb["error"], bb["error"]
    assert _pubacks(worker) == [1, 2]
    assert (stats.batches, stats.stored) == (1, 3)
