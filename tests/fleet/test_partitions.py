"""Telemetry's daily partitions (fleet.partitions): late uploads land in their
day, a day that cannot be made at once goes to the default partition and maintenance
moves it, retention drops whole days and keeps per-cell results, and job queries read
only the job's days."""

from __future__ import annotations

import datetime as dt
import re
import time
from typing import Any

import psycopg
import pytest
from fieldrx.db.session import raw_dsn
from fieldrx.fleet.ingest.pipeline import ingest
from fieldrx.fleet.partitions import maintain
from sqlalchemy import text

from tests.fleet.helpers import JobFixture, record, shard_free_plan, unshard

DAY = 86400.0


@pytest.fixture()
def conn(database_url: str):  # noqa: ANN201
    with psycopg.connect(raw_dsn(database_url), options="-c jit=off") as c:
        yield c


def _today0() -> float:
    """Midnight UTC today, epoch seconds."""
    return float(int(time.time() // DAY) * DAY)


def _batch(job: JobFixture, seqs: range, t0: float) -> list[dict[str, Any]]:
    return [record(job, s, t=t0 + s * 0.1, cell=s % 8) for s in seqs]


def _where(conn: psycopg.Connection[Any], machine_id: int) -> dict[str, int]:
    """Rows of the machine per partition."""
    with conn.transaction():
        rows = conn.execute(
            "SELECT tableoid::regclass::text, count(*) FROM telemetry WHERE machine_id = %s"
            " GROUP BY 1",
            (machine_id,),
        ).fetchall()
    return {unshard(name): n for name, n in rows}  # Citus: a router query names the shard


def _day_name(t: float) -> str:
    return "telemetry_p" + dt.datetime.fromtimestamp(t, dt.UTC).strftime("%Y_%m_%d")


def test_days_old_records_land_in_their_own_day(conn, job) -> None:  # noqa: ANN001
    """An agent back from offline work uploads records 40 days old: their day (beyond the
    premade ones) is made on demand, nothing goes to the default partition, and a resend
    is a duplicate."""
    t_old = _today0() - 40 * DAY + 3600.0
    batch = _batch(job, range(1, 101), t_old)
    r1 = ingest(conn, job.machine_id, batch, "late", 1, True)
    assert (r1.stored, r1.acked_seq, r1.rejected) == (100, 100, [])
    assert _where(conn, job.machine_id) == {_day_name(t_old): 100}
    r2 = ingest(conn, job.machine_id, batch, "late", 1, True)
    assert (r2.stored, r2.duplicates, r2.acked_seq) == (0, 100, 100)
    # records spanning midnight: two days, each in its own partition
    t_mid = _today0() - 20 * DAY - 5.0  # seq s at t_mid + 0.1 s: 50 before, 50 after midnight
    r3 = ingest(conn, job.machine_id, _batch(job, range(1, 101), t_mid), "mid", 1, True)
    assert r3.stored == 100
    where = _where(conn, job.machine_id)
    assert where[_day_name(t_mid)] == 49 and where[_day_name(t_mid + 10)] == 51


def test_a_day_that_cannot_be_made_goes_to_default_then_maintenance_moves_it(
    conn, job, database_url: str
) -> None:  # noqa: ANN001
    """While a long transaction holds the default partition (a report over an unknown
    range, say), the day cannot be attached: the batch is stored in the default partition
    all the same, acknowledged, deduplicated; maintenance later moves it into its day."""
    t_old = _today0() - 61 * DAY + 7200.0
    batch = _batch(job, range(1, 51), t_old)
    with psycopg.connect(raw_dsn(database_url)) as blocker:
        blocker.execute("SELECT count(*) FROM telemetry_default")  # holds ACCESS SHARE
        r1 = ingest(conn, job.machine_id, batch, "blocked", 1, True)
        assert (r1.stored, r1.acked_seq) == (50, 50)
        assert _where(conn, job.machine_id) == {"telemetry_default": 50}
        r2 = ingest(conn, job.machine_id, batch, "blocked", 1, True)  # resend: from default
        assert (r2.stored, r2.duplicates) == (0, 50)
        blocker.rollback()
    res = maintain(conn, 0)
    assert res is not None and res.moved_rows >= 50
    assert _day_name(t_old) in res.created
    assert _where(conn, job.machine_id) == {_day_name(t_old): 50}
    r3 = ingest(conn, job.machine_id, batch, "blocked", 1, True)
    assert (r3.stored, r3.duplicates, r3.acked_seq) == (0, 50, 50)
    with conn.transaction():
        assert conn.execute("SELECT count(*) FROM telemetry_default").fetchone() == (0,)


def test_restored_queue_is_heard_across_days(conn, job) -> None:  # noqa: ANN001
    """A queue restored from an old backup reuses seqs stored weeks ago under new times:
    the stored records lie outside the batch's own days, and the conflict is still found
    (the lookup widens to the stream's first..last record time)."""
    t_old = _today0() - 30 * DAY + 100.0
    assert (
        ingest(conn, job.machine_id, _batch(job, range(1, 201), t_old), "q", 1, True).stored == 200
    )
    again = _batch(job, range(150, 161), _today0() + 60.0)
    r = ingest(conn, job.machine_id, again, "q", 1, True)
    assert r.stream_conflict and r.stored == 0 and r.acked_seq == 149
    # records stored out of order (seq 300-310 first, then the gap 201-299) advance the ack
    t_new = _today0() - 2 * DAY
    r1 = ingest(conn, job.machine_id, _batch(job, range(300, 311), t_new), "q2", 1, True)
    assert r1.acked_seq == 0
    r2 = ingest(conn, job.machine_id, _batch(job, range(1, 300), t_new - 40.0), "q2", 1, True)
    assert (r2.stored, r2.acked_seq, r2.stream_conflict) == (299, 310, False)


def test_retention_drops_whole_old_days_and_keeps_cell_results(conn, job, db) -> None:  # noqa: ANN001
    for days_ago, stream in ((50, "a"), (10, "b"), (1, "c")):
        t = _today0() - days_ago * DAY + 600.0
        assert ingest(conn, job.machine_id, _batch(job, range(1, 41), t), stream, 1, True).stored
    cells_before = db.execute(
        text("SELECT count(*), sum(n_records) FROM job_cells_applied WHERE job_id = :j"),
        {"j": job.job_id},
    ).one()
    assert cells_before[1] == 120
    assert maintain(conn, 0).dropped == []  # 0: keep everything
    try:
        res = maintain(conn, 30)
    finally:
        maintain(conn, 0)  # the session's database is shared: back to keeping everything
    assert res is not None
    assert _day_name(_today0() - 50 * DAY) in res.dropped
    assert all(n < _day_name(_today0() - 30 * DAY) for n in res.dropped)
    assert res.seconds < 5.0
    assert sorted(_where(conn, job.machine_id).values()) == [40, 40]
    db.rollback()
    assert (
        db.execute(
            text("SELECT count(*), sum(n_records) FROM job_cells_applied WHERE job_id = :j"),
            {"j": job.job_id},
        ).one()
        == cells_before
    )


def test_job_queries_read_only_the_jobs_days(conn, job, client, org) -> None:  # noqa: ANN001
    """The report's and the as-applied points' queries name the job's time span: the plan
    touches the job's day only, not the other days in the table."""
    from fieldrx.fleet.reports import build_report  # noqa: F401 (the query under test)

    for days_ago in (9, 8, 7):
        t = _today0() - days_ago * DAY + 900.0
        ingest(conn, job.machine_id, _batch(job, range(1, 21), t), f"d{days_ago}", 1, True)
    with conn.transaction():
        span = conn.execute(
            "SELECT first_t, last_t, n_records FROM telemetry_job_spans"
            " WHERE machine_id = %s AND job_id = %s",
            (job.machine_id, job.job_id),
        ).fetchone()
        assert span is not None and span[2] == 60
        plan = "\n".join(
            r[0]
            for r in conn.execute(
                "EXPLAIN SELECT * FROM telemetry WHERE machine_id = %s AND job_id = %s"
                " AND t BETWEEN %s AND %s",
                (job.machine_id, job.job_id, span[0], span[1]),
            ).fetchall()
        )
    scanned = set(re.findall(r" on (telemetry_\w+) ", shard_free_plan(plan)))
    assert scanned == {_day_name(_today0() - d * DAY) for d in (9, 8, 7)}, plan
    r = client.get(f"/api/v1/jobs/{job.job_id}/as-applied", headers=org.headers())
    assert r.status_code == 200 and r.json()["total"] == 60, r.text
    rep = client.get(f"/api/v1/jobs/{job.job_id}/report", headers=org.headers())
    assert rep.status_code == 200 and rep.json()["n_records"] == 60, rep.text


def test_maintenance_command(database_url: str, capsys) -> None:  # noqa: ANN001
    """`fieldrx telemetry-maintenance` runs the same maintenance and prints what it did."""
    import json

    from fieldrx.cli import main

    assert main(["telemetry-maintenance", "--retention-days", "0"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["retention_days"] == 0 and out["dropped"] == [] and out["partitions"] >= 5
    with pytest.raises(SystemExit):
        main(["telemetry-maintenance", "--retention-days", "-1"])


def test_a_batch_cannot_make_a_partition_per_past_day_it_names(conn, job) -> None:  # noqa: ANN001
    """30 records on 30 days of 2000-2003 made 30 partitions (up to ~20,000 per batch):
    days far in the past go to the default partition, and a batch makes at most a few
    past days; every record is stored and acknowledged all the same."""

    def parts() -> set[str]:
        with conn.transaction():
            rows = conn.execute(
                "SELECT c.relname FROM pg_inherits i JOIN pg_class c ON c.oid = i.inhrelid"
                " WHERE i.inhparent = 'telemetry'::regclass"
            ).fetchall()
        return {r[0] for r in rows}

    before = parts()
    t2000 = 946_684_800.0 + 3600.0
    ancient = [record(job, s, t=t2000 + s * 37 * DAY, cell=s % 8) for s in range(1, 31)]
    r = ingest(conn, job.machine_id, ancient, "ancient", 1, True)
    assert (r.stored, r.acked_seq, r.rejected) == (30, 30, [])
    assert parts() == before
    assert _where(conn, job.machine_id) == {"telemetry_default": 30}
    recent = [record(job, s, t=_today0() - (10 + s) * DAY + 60.0, cell=s % 8) for s in range(1, 11)]
    r = ingest(conn, job.machine_id, recent, "recent", 1, True)
    assert (r.stored, r.acked_seq) == (10, 10)
    from fieldrx.fleet.partitions import MAX_NEW_DAYS

    assert len(parts() - before) <= MAX_NEW_DAYS


def test_far_past_records_are_flagged_and_maintenance_keeps_them_in_default(
    conn, job, client, org
) -> None:  # noqa: ANN001
    """Records dated more than ON_DEMAND_DAYS ago are stored in the default partition and
    flagged in the ack and by a far_past_records alert; maintenance moves the default
    partition's recent rows into their days but never makes the old days."""
    from fieldrx.fleet.partitions import ON_DEMAND_DAYS

    def parts() -> set[str]:
        with conn.transaction():
            rows = conn.execute(
                "SELECT c.relname FROM pg_inherits i JOIN pg_class c ON c.oid = i.inhrelid"
                " WHERE i.inhparent = 'telemetry'::regclass"
            ).fetchall()
        return {r[0] for r in rows}

    t2001 = 978_307_200.0 + 3600.0
    ancient = [record(job, s, t=t2001 + s * 11 * DAY, cell=s % 8) for s in range(1, 8)]
    # inside the bound, not flagged; the oldest of five past days goes to the default
    # partition (a batch makes MAX_NEW_DAYS), for maintenance to move
    edge = _today0() - (ON_DEMAND_DAYS - 2) * DAY + 60.0
    ancient.append(record(job, 8, t=edge, cell=0))
    ancient += [record(job, 9 + i, t=_today0() - (100 + i) * DAY, cell=0) for i in range(4)]
    r = ingest(conn, job.machine_id, ancient, "far", 1, True)
    assert (r.stored, r.acked_seq, r.rejected) == (12, 12, [])
    assert _where(conn, job.machine_id)["telemetry_default"] == 8
    assert [f["seq"] for f in r.flagged] == list(range(1, 8))
    assert "400 days" in r.flagged[0]["reason"]
    assert b'"flagged"' in r.to_json()

    def far_alerts() -> list[dict[str, Any]]:
        got = client.get(
            "/api/v1/alerts",
            params={"machine_id": job.machine_id, "kind": "far_past_records"},
            headers=org.headers(),
        )
        assert got.status_code == 200, got.text
        return list(got.json()["items"])

    far = far_alerts()
    assert len(far) == 1 and "7 record(s) dated from 2001-01-12" in far[0]["message"], far
    # a later batch of old records does not open a second alert
    again = [record(job, 13, t=t2001 + 99 * DAY, cell=0)]
    assert ingest(conn, job.machine_id, again, "far", 1, True).flagged[0]["seq"] == 13
    assert len(far_alerts()) == 1
    before = parts()
    res = maintain(conn, 0)
    assert res is not None and res.far_past_rows >= 8 and res.moved_rows >= 1
    made = parts() - before
    assert _day_name(edge) in made, made
    assert min(made) >= _day_name(edge - 2 * DAY), made  # no day beyond the bound
    where = _where(conn, job.machine_id)
    assert where["telemetry_default"] == 8 and where[_day_name(edge)] == 1, where
