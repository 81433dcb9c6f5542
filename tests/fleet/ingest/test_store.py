"""The store stage against PostgreSQL: the batch transaction (its lock before the reads,
all or nothing) and the COPY into ``telemetry``."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import psycopg
import pytest
from fieldrx.db.session import raw_dsn
from fieldrx.fleet.db import connect
from fieldrx.fleet.ingest.model import IngestResult
from fieldrx.fleet.ingest.store import (
    begin,
    commit,
    copy_rows,
    make_days,
    pipelined,
    store_alone,
)
from fieldrx.fleet.ingest.validate import validate
from fieldrx.fleet.telemetry_row import TelemetryRow

from tests.fleet.helpers import JobFixture, record

PROBE_NS = 7999


def _rows(job: JobFixture, *seqs: int) -> list[TelemetryRow]:
    valid, rejected, _, _ = validate([record(job, q) for q in seqs], job.machine_id, "st")
    assert not rejected
    return list(valid.values())


def _stored(conn: psycopg.Connection[Any], job: JobFixture) -> int:
    sql = "SELECT count(*) FROM telemetry WHERE machine_id = %s AND stream = 'st'"
    return int(conn.execute(sql, (job.machine_id,)).fetchone()[0])  # type: ignore[index]


@dataclass
class Probe:
    """A batch's work that records what the transaction did, in order."""

    machine_id: int
    rows: list[TelemetryRow]
    lock_ns: int = PROBE_NS
    result: IngestResult = field(default_factory=lambda: IngestResult(0, 0))
    calls: list[Any] = field(default_factory=list)

    def prepare(self, conn: psycopg.Connection[Any]) -> None:
        idle = conn.info.transaction_status == psycopg.pq.TransactionStatus.IDLE
        self.calls.append(("prepare", idle))
        make_days(conn, self.rows)

    def read(self, cur: psycopg.Cursor[Any]) -> None:
        cur.execute(
            "SELECT count(*) FROM pg_locks WHERE locktype = 'advisory' AND granted"
            " AND classid = %s AND objid = %s AND pid = pg_backend_pid()",
            (self.lock_ns, self.machine_id),
        )

    def opened(self, row: Any) -> None:
        self.calls.append(("locked", row[0]))

    def store(self, cur: psycopg.Cursor[Any]) -> None:
        self.calls.append("store")
        copy_rows(cur, self.rows)

    def finish(self, cur: psycopg.Cursor[Any]) -> list[dict[str, Any]]:
        self.calls.append("finish")
        return [{"type": "probe"}]


def test_a_batch_runs_in_its_own_transaction_under_its_machines_lock(
    database_url: str, job: JobFixture
) -> None:
    probe = Probe(job.machine_id, _rows(job, 1, 2, 3))
    with connect(raw_dsn(database_url)) as conn:
        assert store_alone(conn, probe) is probe.result
        assert probe.calls == [("prepare", True), ("locked", 1), "store", "finish"]
        assert _stored(conn, job) == 3
        assert conn.info.transaction_status == psycopg.pq.TransactionStatus.IDLE


def test_a_failed_or_unfinished_batch_leaves_nothing(database_url: str, job: JobFixture) -> None:
    rows = _rows(job, 1, 2)
    with connect(raw_dsn(database_url)) as conn:
        make_days(conn, rows)
        with pytest.raises(RuntimeError, match="without commit"):
            with pipelined(conn) as cur:
                begin(cur)
                copy_rows(cur, rows)
        with pytest.raises(ZeroDivisionError):
            with pipelined(conn) as cur:
                begin(cur)
                copy_rows(cur, rows)
                _ = 1 / 0
        assert _stored(conn, job) == 0
        with pipelined(conn) as cur:
            begin(cur)
            copy_rows(cur, [])  # nothing new: no COPY at all
            copy_rows(cur, rows)
            commit(cur)
        assert _stored(conn, job) == 2
