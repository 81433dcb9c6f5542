""" (the Citus path): per-cell results carry the machine, and a machine's
track and chart queries name the days they read.

* Migration 0014_machine_keys: ``job_cells_applied`` rows written before it are all there
  after it, each with its job's machine (the distribution column), keyed
  (machine, job, cell); a row naming another machine than its job's is refused; the
  downgrade keeps them too.
* ``GET /machines/{id}/track`` without a range read every day's partition of the table
  (the query had no bound on ``t``); it now reads the machine's latest day only
  (EXPLAIN), and a range reads the range's days.
"""

from __future__ import annotations

import datetime as dt
import re
import time
import uuid
from typing import Any

import psycopg
import pytest
from alembic import command
from fieldrx.api.fleet import CHART_WHERE, TRACK_WHERE
from fieldrx.db.bootstrap import alembic_config, drop_database, ensure_database
from fieldrx.db.session import make_engine, raw_dsn
from fieldrx.fleet.ingest.pipeline import ingest
from fieldrx.fleet.partitions import machine_window
from sqlalchemy.orm import Session

from tests.conftest import PG
from tests.fleet.helpers import JobFixture, record, shard_free_plan

DAY = 86400.0


def _seed_jobs(url: str) -> list[tuple[int, int]]:
    """Two machines with a job each (ORM at head): [(machine id, job id)]."""
    from fieldrx.db.models import (
        Field,
        Job,
        Machine,
        Organisation,
        Plan,
        Prescription,
        PrescriptionVersion,
    )
    from geoalchemy2.shape import from_shape
    from shapely.geometry import LineString, MultiPolygon, Polygon

    eng = make_engine(url)
    out = []
    try:
        with Session(eng) as s:
            org = Organisation(name=f"o-{uuid.uuid4().hex[:6]}")
            s.add(org)
            s.flush()
            f = Field(
                organisation_id=org.id,
                name="f",
                boundary=from_shape(
                    MultiPolygon([Polygon.from_bounds(112.3, 32.1, 112.31, 32.11)])
                ),
                utm_epsg=32649,
                area_m2=1e6,
            )
            s.add(f)
            s.flush()
            p = Plan(
                organisation_id=org.id, field_id=f.id, params={}, metrics={}, heading_deg=0.0,
                n_cells=100, route=from_shape(LineString([(112.3, 32.1), (112.31, 32.11)])),
            )  # fmt: skip
            s.add(p)
            s.flush()
            rx = Prescription(organisation_id=org.id, plan_id=p.id, model="uniform")
            s.add(rx)
            s.flush()
            s.add(PrescriptionVersion(prescription_id=rx.id, version=1))
            for i in range(2):
                m = Machine(
                    organisation_id=org.id, name=f"m{i}", width_m=6.0, lag_s=1.5,
                    calibration={}, controller={}, speed_min_m_s=0.5, speed_max_m_s=3.0,
                )  # fmt: skip
                s.add(m)
                s.flush()
                j = Job(
                    organisation_id=org.id, prescription_id=rx.id, prescription_version=1,
                    machine_id=m.id, n_cells=100,
                )  # fmt: skip
                s.add(j)
                s.flush()
                out.append((m.id, j.id))
            s.commit()
    finally:
        eng.dispose()
    return out


def test_0014_keeps_every_cell_row_and_adds_the_machine() -> None:
    name = f"fieldrx_mig_{uuid.uuid4().hex[:8]}"
    url = PG.replace("postgresql://", "postgresql+psycopg://", 1) + f"/{name}"
    dsn = f"{PG}/{name}"
    ensure_database(url)
    try:
        cfg = alembic_config(url)
        command.upgrade(cfg, "head")
        jobs = _seed_jobs(url)
        command.downgrade(cfg, "0013_cells")
        with psycopg.connect(dsn, autocommit=True) as conn:
            for k, (_, j) in enumerate(jobs):
                conn.execute(
                    "INSERT INTO job_cells_applied (job_id, seq, n_records, target_rate_sum,"
                    " applied_rate_sum, first_t, last_t) SELECT %s, s, s + %s, s * 2.0, s * 1.5,"
                    " now(), now() FROM generate_series(0, 99) s",
                    (j, k),
                )
            before = conn.execute(
                "SELECT job_id, seq, n_records, target_rate_sum, applied_rate_sum"
                " FROM job_cells_applied ORDER BY job_id, seq"
            ).fetchall()
        assert len(before) == 200
        command.upgrade(cfg, "head")
        with psycopg.connect(dsn, autocommit=True) as conn:
            after = conn.execute(
                "SELECT machine_id, job_id, seq, n_records, target_rate_sum, applied_rate_sum"
                " FROM job_cells_applied ORDER BY job_id, seq"
            ).fetchall()
            assert [r[1:] for r in after] == before  # every row, unchanged
            machine_of = {j: m for m, j in jobs}
            assert all(r[0] == machine_of[r[1]] for r in after)
            key = conn.execute(
                "SELECT pg_get_constraintdef(oid) FROM pg_constraint"
                " WHERE conname = 'job_cells_applied_pkey'"
            ).fetchone()
            assert key is not None and key[0] == "PRIMARY KEY (machine_id, job_id, seq)"
            # the copy of the machine stays true to the job
            (m0, j0), (m1, _) = jobs
            with pytest.raises(psycopg.errors.ForeignKeyViolation):
                conn.execute(
                    "INSERT INTO job_cells_applied (machine_id, job_id, seq, n_records,"
                    " target_rate_sum, applied_rate_sum) VALUES (%s, %s, 500, 1, 1, 1)",
                    (m1, j0),
                )
        command.downgrade(cfg, "0013_cells")
        with psycopg.connect(dsn, autocommit=True) as conn:
            again = conn.execute(
                "SELECT job_id, seq, n_records, target_rate_sum, applied_rate_sum"
                " FROM job_cells_applied ORDER BY job_id, seq"
            ).fetchall()
        assert again == before
    finally:
        drop_database(url)


def _partitions(conn: psycopg.Connection[Any], sql: str, params: dict[str, Any]) -> set[str]:
    """The telemetry partitions the plan of ``sql`` (the routes' ``:name`` parameters) reads."""
    for name in ("m", "t0", "t1"):
        sql = sql.replace(f":{name}", f"%({name})s")
    with conn.transaction():
        plan = "\n".join(r[0] for r in conn.execute("EXPLAIN " + sql, params).fetchall())
    plan = shard_free_plan(plan)
    return set(re.findall(r"\b(telemetry_(?:p\d{4}_\d{2}_\d{2}|default))\b", plan))


def _day(t: float) -> str:
    return "telemetry_p" + dt.datetime.fromtimestamp(t, dt.UTC).strftime("%Y_%m_%d")


def test_track_reads_only_the_days_it_shows(
    client,
    db,
    org,
    job: JobFixture,
    database_url: str,  # noqa: ANN001
) -> None:
    now = time.time()
    noon = float(int(now // DAY) * DAY) + DAY / 2
    # a machine that worked 5 and 3 days ago and today (before now: no future records)
    days = [noon - 5 * DAY, noon - 3 * DAY, min(noon, now - 600.0)]
    with psycopg.connect(raw_dsn(database_url), options="-c jit=off") as conn:
        for k, t0 in enumerate(days):
            recs = [record(job, 100 * k + s, t=t0 + s) for s in range(1, 51)]
            assert ingest(conn, job.machine_id, recs, "days", 1, True).stored == 50
        every = {
            r[0]
            for r in conn.execute(
                "SELECT c.relname FROM pg_inherits i JOIN pg_class c ON c.oid = i.inhrelid"
                " WHERE i.inhparent = 'public.telemetry'::regclass"
            ).fetchall()
        }
        assert {_day(t) for t in days} <= every and len(every) >= 8  # + premade days, default

        # no range: the machine's latest day
        w = machine_window(db, job.machine_id, None, None)
        assert w["t1"].timestamp() == pytest.approx(days[2] + 50, abs=1e-3)
        params = {**w, "m": job.machine_id}
        for sql in (
            f"SELECT count(*) FROM telemetry WHERE {TRACK_WHERE}",
            f"SELECT seq FROM telemetry WHERE {TRACK_WHERE} ORDER BY t, seq LIMIT 10",
            f"SELECT seq FROM telemetry WHERE {CHART_WHERE} ORDER BY t DESC, seq LIMIT 10",
        ):
            read = _partitions(conn, sql, params)
            assert read <= {_day(days[2]), _day(days[2] - DAY)}, (sql, read)
            assert _day(days[0]) not in read and _day(days[1]) not in read
        # before: the same query without the bound planned every partition
        unbounded = _partitions(
            conn, "SELECT count(*) FROM telemetry WHERE machine_id = %(m)s AND geom IS NOT NULL",
            {"m": job.machine_id},
        )  # fmt: skip
        assert unbounded == every

        # a range given by its start only: to the machine's last record, those days only
        w = machine_window(
            db, job.machine_id, dt.datetime.fromtimestamp(days[1] - 60, dt.UTC), None
        )
        read = _partitions(
            conn, f"SELECT count(*) FROM telemetry WHERE {TRACK_WHERE}", {**w, "m": job.machine_id}
        )
        assert _day(days[0]) not in read and {_day(days[1]), _day(days[2])} <= read
        assert not any(p > _day(days[2]) for p in read if p != "telemetry_default")

    # the route: no range shows the latest day's records; an open start reaches back
    base = f"/api/v1/machines/{job.machine_id}/track"
    r = client.get(base, headers=org.headers())
    page = r.json()
    assert page["total"] == 50
    # ... and says which range it answered (not silently less than everything)
    t_from = dt.datetime.fromisoformat(r.headers["X-FieldRx-From"])
    t_to = dt.datetime.fromisoformat(r.headers["X-FieldRx-To"])
    assert t_from.timestamp() > days[1]
    assert t_to.timestamp() == pytest.approx(days[2] + 50, abs=1e-3)
    assert [f["properties"]["seq"] for f in page["features"]][:2] == [201, 202]
    to = dt.datetime.fromtimestamp(days[2] + 100, dt.UTC).isoformat()
    page = client.get(base, params={"to": to, "limit": 5}, headers=org.headers()).json()
    assert page["total"] == 150 and page["features"][0]["properties"]["seq"] == 1
    r = client.get(f"/api/v1/machines/{job.machine_id}/telemetry?limit=3", headers=org.headers())
    assert r.headers["X-FieldRx-From"] == t_from.isoformat()
    chart = r.json()
    assert chart["seq"] == [248, 249, 250]
