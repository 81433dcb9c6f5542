"""Telemetry at fleet scale: one job's report and track with 20 million other rows.

 The acceptance test: with 20 million telemetry rows of other machines in the table, the
as-applied report and the track query of one job answer in p50 <= 100 ms, and the
retention drop of one day's partition takes < 1 s.

Steps, all on a throw-away database at head (telemetry partitioned by day, migration
0010):

1. an organisation, a field (``--field`` metres, near the seed-001 plot), a 2.3 m
   spreader, a plan, a uniform prescription and a job; the edge simulator
   (``fieldrx-edge simulate --server``) drives it against a uvicorn API, so the job's
   records arrive through the real ingest;
2. baseline timings of the job's queries (the table holds only the job);
3. ``--rows`` rows of ``--machines`` other machines over ``--days`` days up to the job's
   day: each past day is filled with INSERT .. SELECT generate_series into a plain table
   and attached as that day's partition (indexes built in bulk: the fast way to load
   history, not what ingest does); the job's own day gets its share by INSERT into the
   live partition, so the job shares its partition with other machines' rows; ANALYZE;
4. the same timings (p50 / p90 of ``--repeat`` runs each, and the CPU time per call of
   this process, the API server and the database's backends: on a shared machine the
   wall time includes waiting for a core): the report as built by
   ``fleet.reports.build_report`` (uncached), ``GET /jobs/{id}/report`` (cache check),
   ``GET /jobs/{id}/as-applied`` (the job's track points) and
   ``GET /machines/{id}/track`` over the job's time range, all through the API;
5. EXPLAIN of every hot telemetry query: how many day partitions each one reads;
6. retention: ``fleet.partitions.maintain`` with the retention set so exactly the
   oldest day goes; its time.

The last line is one JSON object with every figure.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from tests.fleet.procs import BIN, start_api  # noqa: E402
from tests.support import SEED001_CAL, feature, machine_body  # noqa: E402

PG = os.environ.get("FIELDRX_TEST_PG", "postgresql://postgres@127.0.0.1:5432")
DAY = 86400.0
LON0, LAT0 = 112.32, 32.13


def make_db() -> str:
    from alembic import command
    from fieldrx.db.bootstrap import alembic_config, ensure_database

    url = (
        PG.replace("postgresql://", "postgresql+psycopg://", 1)
        + f"/fieldrx_bench_tq_{uuid.uuid4().hex[:8]}"
    )
    ensure_database(url)
    command.upgrade(alembic_config(url), "head")
    return url


def make_org(url: str) -> tuple[int, str]:
    from fieldrx.auth.service import (
        add_membership,
        create_organisation,
        create_user,
        issue_user_token,
    )
    from fieldrx.db.session import make_engine
    from sqlalchemy.orm import Session

    eng = make_engine(url)
    with Session(eng) as s:
        org = create_organisation(s, f"bench-{uuid.uuid4().hex[:6]}")
        user = create_user(s, f"a@{org.name}.test", "correct horse battery", "A")
        add_membership(s, user, org, "admin")
        token, _ = issue_user_token(s, user.id, org.id, "admin")
        s.commit()
        oid = org.id
    eng.dispose()
    return oid, token


def rect(length_m: float, width_m: float) -> dict[str, Any]:
    dlon = length_m / 94_300.0
    dlat = width_m / 110_900.0
    ring = [
        [LON0, LAT0],
        [LON0 + dlon, LAT0],
        [LON0 + dlon, LAT0 + dlat],
        [LON0, LAT0 + dlat],
        [LON0, LAT0],
    ]
    return {"type": "Polygon", "coordinates": [ring]}


def drive_job(base: str, token: str, field_m: tuple[float, float], tmp: Path) -> dict[str, Any]:
    """Field, machine, plan, prescription, job; the simulator drives it through the API."""
    import httpx

    c = httpx.Client(base_url=base, headers={"Authorization": f"Bearer {token}"}, timeout=120)
    fld = c.post("/api/v1/fields", json=feature(rect(*field_m), name="bench field"))
    assert fld.status_code == 201, fld.text
    cal = {**SEED001_CAL, "min_rpm": 10.0}
    m = c.post("/api/v1/machines", json=machine_body("bench", 2.3, calibration=cal)).json()
    dev = c.post(f"/api/v1/machines/{m['id']}/device-token").json()["token"]
    plan = c.post(
        f"/api/v1/fields/{fld.json()['id']}/plans",
        json={"swath_width_m": 2.3, "cell_length_m": 5.0, "headland_passes": 0},
    )
    assert plan.status_code == 201, plan.text
    rx = c.post(
        f"/api/v1/plans/{plan.json()['id']}/prescriptions",
        json={"model": "uniform", "params": {"rate_kg_ha": 300.0}, "machine_id": m["id"]},
    )
    assert rx.status_code == 201, rx.text
    job = c.post("/api/v1/jobs", json={"prescription_id": rx.json()["id"], "machine_id": m["id"]})
    assert job.status_code == 201, job.text
    jid = job.json()["id"]
    assert c.post(f"/api/v1/jobs/{jid}/state", json={"state": "sent"}).status_code == 200
    pkg = httpx.get(
        f"{base}/api/v1/device/jobs/{jid}/package", headers={"Authorization": f"Bearer {dev}"}
    )
    assert pkg.status_code == 200, pkg.text
    (tmp / "job.json").write_bytes(pkg.content)
    t0 = time.perf_counter()
    out = subprocess.run(
        [str(BIN / "fieldrx-edge"), "simulate", str(tmp / "job.json"), "--server", base,
         "--token", dev, "--json", "--seed", "3", "--state-dir", str(tmp / "state"),
         "--compare-runs", "0"],
        cwd=ROOT, capture_output=True, text=True, timeout=1800,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    sim = json.loads(out.stdout.strip().splitlines()[-1])
    assert sim["telemetry_drained"] is True, sim
    print(
        f"job {jid}: {plan.json().get('n_cells')} cells, {sim['telemetry']['last_seq']} records"
        f" driven by the simulator through the API in {time.perf_counter() - t0:.1f} s"
    )
    return {"job_id": jid, "machine_id": m["id"], "n_records": sim["telemetry"]["last_seq"]}


# the other machines' rows: one day of them, as INSERT .. SELECT into table {table}
OTHER_ROWS = """
INSERT INTO {table} (machine_id, stream, seq, t, job_id, geom, fix_quality, hdop,
    speed_raw_m_s, speed_filtered_m_s, heading_deg, cell_seq, target_rate_kg_ha,
    applied_rate_kg_ha, target_shaft_rpm, actual_shaft_rpm, duty, implement_down, alarms,
    queue_backlog, fix_period_s)
SELECT m.id, 'b' || m.id, %(day)s::int8 * 100000000 + i,
    %(t0)s + make_interval(secs => i * 0.1 + m.k * 0.01),
    1000000 + m.k * 1000 + %(day)s, ST_SetSRID(ST_MakePoint(112.3 + m.k * 1e-3 + i * 1e-7,
    32.1 + (i %% 500) * 1e-5), 4326), 4, 0.7, 1.7, 1.7, 0.0, i / 30, 300.0, 299.0 + i %% 3,
    30.0, 29.9, 41.5, true, '{{}}'::varchar[], 0, 0.1
FROM (SELECT id, row_number() OVER (ORDER BY id) - 1 AS k FROM machines
      WHERE name LIKE 'other-%%') m, generate_series(1, %(per)s) i
"""


def load_others(
    dsn: str, org: int, n_machines: int, rows: int, days: list[int], live_day: int
) -> float:
    """``rows`` rows of ``n_machines`` other machines spread over ``days`` (UTC day numbers
    since 2000-01-01); seconds taken."""
    import psycopg
    from fieldrx.fleet.partitions import PARENT, day_start, ensure_days

    t0 = time.perf_counter()
    per = rows // (len(days) * n_machines)
    with psycopg.connect(dsn, autocommit=True) as conn:
        conn.execute(
            "INSERT INTO machines (organisation_id, name, implement_type, width_m, lag_s,"
            " calibration, controller, antenna_forward_m, antenna_lateral_m, speed_min_m_s,"
            " speed_max_m_s) SELECT %s, 'other-' || g, 'spreader', 6, 1.5, '{}', '{}', 0, 0,"
            " 0.5, 3 FROM generate_series(1, %s) g",
            (org, n_machines),
        )
        conn.execute("SET timezone = 'UTC'")
        for d in days:
            start = day_start(d)
            name = "telemetry_p" + start.strftime("%Y_%m_%d")
            t1 = time.perf_counter()
            params = {"day": d, "t0": start, "per": per}
            if d == live_day:  # the job's own day: into the live partition, index by index
                ensure_days(conn, [d * 86_400_000_000])
                conn.execute(OTHER_ROWS.format(table="telemetry"), params)
                how = "INSERT into the live partition"
            else:
                with conn.transaction():
                    conn.execute(f"DROP TABLE IF EXISTS {name}")  # a premade, empty day
                    conn.execute(
                        f"CREATE TABLE {name} (LIKE telemetry INCLUDING DEFAULTS INCLUDING"
                        " CONSTRAINTS)"
                    )
                    conn.execute(OTHER_ROWS.format(table=name), params)
                    end = day_start(d + 1)
                    conn.execute(
                        f"ALTER TABLE {name} ADD CONSTRAINT {name}_t CHECK"
                        f" (t >= '{start.isoformat()}' AND t < '{end.isoformat()}')"
                    )
                    conn.execute(
                        f"ALTER TABLE {PARENT} ATTACH PARTITION {name} FOR VALUES FROM"
                        f" ('{start.isoformat()}') TO ('{end.isoformat()}')"
                    )
                    conn.execute(f"ALTER TABLE {name} DROP CONSTRAINT {name}_t")
                how = "plain table attached"
            print(
                f"  {start.date()}: {per * n_machines:,} rows ({how}) in"
                f" {time.perf_counter() - t1:.1f} s",
                flush=True,
            )
        conn.execute(
            "INSERT INTO telemetry_job_spans (machine_id, job_id, first_t, last_t, n_records)"
            " SELECT machine_id, job_id, min(t), max(t), count(*) FROM telemetry t"
            " JOIN machines m ON m.id = t.machine_id AND m.name LIKE 'other-%'"
            " GROUP BY machine_id, job_id"
        )
        conn.execute("ANALYZE telemetry")
        conn.execute("ANALYZE telemetry_job_spans")
    return time.perf_counter() - t0


def timed(fn: Any, repeat: int, db_name: str) -> dict[str, float]:
    """Wall time per call (p50, p90, max) and CPU time per call of everything that works
    for it (this process, the API server, the database's backends; ``bench.ingest``'s
    accounting): on a shared machine the wall time includes waiting for a core, the CPU
    time is the call's own cost."""
    from bench.ingest import cpu_seconds, cpu_used

    fn()  # warm: plans, caches
    ms = []
    cpu0 = cpu_seconds(db_name)
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ms.append((time.perf_counter() - t0) * 1000.0)
    cpu1 = cpu_seconds(db_name)
    ms.sort()
    return {
        "p50_ms": round(statistics.median(ms), 1),
        "p90_ms": round(ms[int(0.9 * (len(ms) - 1))], 1),
        "max_ms": round(ms[-1], 1),
        "cpu_ms": round(sum(cpu_used(cpu0, cpu1).values()) / repeat * 1000.0, 1),
    }


def measure(url: str, base: str, token: str, job: dict[str, Any], repeat: int) -> dict[str, Any]:
    import httpx
    from fieldrx.db.models import Job
    from fieldrx.db.session import make_engine
    from fieldrx.fleet.reports import build_report
    from sqlalchemy.orm import Session

    c = httpx.Client(base_url=base, headers={"Authorization": f"Bearer {token}"}, timeout=60)
    jid, mid = job["job_id"], job["machine_id"]
    db_name = url.rsplit("/", 1)[1]
    eng = make_engine(url)
    out: dict[str, Any] = {}
    with Session(eng) as s:
        j = s.get(Job, jid)
        assert j is not None

        def report() -> None:
            rep = build_report(s, j)
            assert rep.n_records == job["n_records"], (rep.n_records, job["n_records"])
            s.rollback()

        out["report_build"] = timed(report, repeat, db_name)
    eng.dispose()
    summary = c.get(f"/api/v1/jobs/{jid}/summary").json()
    t_from, t_to = summary["first_record_at"], summary["last_record_at"]

    def get(path: str, params: dict[str, Any] | None = None, check: Any = None) -> Any:
        def f() -> None:
            r = c.get(path, params=params)
            assert r.status_code == 200, r.text
            if check is not None:
                check(r.json())

        return f

    def same(body: dict[str, Any]) -> None:
        assert body["n_records"] == job["n_records"], (body["n_records"], job["n_records"])

    out["report_api"] = timed(get(f"/api/v1/jobs/{jid}/report", check=same), repeat, db_name)
    out["as_applied_points_api"] = timed(get(f"/api/v1/jobs/{jid}/as-applied"), repeat, db_name)

    def iso(v: Any) -> str:
        return v if isinstance(v, str) else dt.datetime.fromtimestamp(v, dt.UTC).isoformat()

    rng = {"from": iso(t_from), "to": iso(t_to)}  # the endpoint's page (1,000)
    out["track_api"] = timed(get(f"/api/v1/machines/{mid}/track", rng), repeat, db_name)
    return out


HOT = {
    # name: (SQL, which parameters) -- the queries as the code issues them
    "report rows (fleet.reports)": (
        "SELECT t, cell_seq, applied_rate_kg_ha FROM telemetry WHERE machine_id = %(m)s"
        " AND job_id = %(j)s AND t BETWEEN %(t0)s AND %(t1)s ORDER BY t, stream, seq"
    ),
    "report cache key": (
        "SELECT count(*), max(t) FROM telemetry WHERE job_id = %(j)s AND machine_id = %(m)s"
        " AND t BETWEEN %(t0)s AND %(t1)s"
    ),
    "as-applied points / exports": (
        "SELECT t, geom FROM telemetry WHERE machine_id = %(m)s AND job_id = %(j)s"
        " AND t BETWEEN %(t0)s AND %(t1)s AND geom IS NOT NULL ORDER BY t, seq"
    ),
    "machine track over the job's range": (
        "SELECT seq, t FROM telemetry WHERE machine_id = %(m)s AND geom IS NOT NULL"
        " AND t >= %(t0)s AND t <= %(t1)s ORDER BY t, seq LIMIT 1000"
    ),
    "ingest dedup lookup (batch range)": (
        "SELECT seq, t FROM telemetry WHERE machine_id = %(m)s AND stream = %(s)s"
        " AND seq BETWEEN 1 AND 500 AND t BETWEEN %(t0)s AND %(t1)s"
    ),
    "ingest ack advance (stream range)": (
        "SELECT seq FROM telemetry WHERE machine_id = %(m)s AND stream = %(s)s AND seq > 100"
        " AND t BETWEEN %(t0)s AND %(t1)s ORDER BY seq LIMIT 2000"
    ),
    "alert history (fleet.alerts)": (
        "SELECT t FROM telemetry WHERE machine_id = %(m)s AND t >= %(t0)s AND t < %(t1)s ORDER BY t"
    ),
}


def explain_all(dsn: str, job: dict[str, Any]) -> dict[str, Any]:
    """Per hot query: day partitions in its plan / day partitions in the table."""
    import psycopg

    out: dict[str, Any] = {}
    with psycopg.connect(dsn, options="-c jit=off") as conn:
        total = conn.execute(
            "SELECT count(*) FROM pg_inherits WHERE inhparent = 'telemetry'::regclass"
        ).fetchone()[0]
        t0, t1 = conn.execute(
            "SELECT first_t, last_t FROM telemetry_job_spans WHERE machine_id = %s AND job_id = %s",
            (job["machine_id"], job["job_id"]),
        ).fetchone()
        stream = conn.execute(
            "SELECT stream FROM telemetry_streams WHERE machine_id = %s ORDER BY n_records DESC",
            (job["machine_id"],),
        ).fetchone()[0]
        p = {"m": job["machine_id"], "j": job["job_id"], "t0": t0, "t1": t1, "s": stream}
        for name, sql in HOT.items():
            plan = "\n".join(r[0] for r in conn.execute("EXPLAIN " + sql, p).fetchall())
            parts = set(re.findall(r" on (telemetry_(?:p\d{4}_\d\d_\d\d|default))\b", plan))
            out[name] = len(parts)
            print(f"  {name}: reads {len(parts)} of {total} partitions")
    out["partitions_total"] = total
    return out


def retention_drop(dsn: str, days: list[int]) -> dict[str, Any]:
    """``maintain`` with the retention set so that exactly the oldest loaded day goes."""
    import psycopg
    from fieldrx.fleet.partitions import maintain

    oldest = min(days)
    now_day = int(time.time() // DAY) - 10957  # days since 2000-01-01
    name = "telemetry_p" + (
        dt.datetime(2000, 1, 1, tzinfo=dt.UTC) + dt.timedelta(days=oldest)
    ).strftime("%Y_%m_%d")
    keep = now_day - oldest - 1  # whole days newer than now - keep: the oldest ends before
    with psycopg.connect(dsn, options="-c jit=off") as conn:
        rows = conn.execute(
            "SELECT count(*) FROM telemetry WHERE t >= %s AND t < %s",
            (dt.datetime(2000, 1, 1, tzinfo=dt.UTC) + dt.timedelta(days=oldest),
             dt.datetime(2000, 1, 1, tzinfo=dt.UTC) + dt.timedelta(days=oldest + 1)),
        ).fetchone()[0]  # fmt: skip
        heap, total = conn.execute(
            "SELECT pg_relation_size(%s), pg_total_relation_size(%s)", (name, name)
        ).fetchone()
        conn.commit()
        res = maintain(conn, keep)
        assert res is not None
        maintain(conn, 0)
    print(
        f"retention {keep} days: dropped {res.dropped} ({rows:,} rows) in {res.seconds:.3f} s"
        " (the whole maintenance run: default-partition check, pg_partman run_maintenance)"
    )
    # the oldest loaded day, and only days before it (premade, empty: small --days runs)
    assert name in res.dropped and max(res.dropped) == name, res.dropped
    print(
        f"a day's partition: {rows:,} rows, {total / 2**20:.0f} MiB with its indexes"
        f" ({total / max(rows, 1):.0f} bytes/row; heap {heap / max(rows, 1):.0f})"
    )
    return {
        "retention_days": keep,
        "dropped": res.dropped,
        "rows": rows,
        "seconds": res.seconds,
        "day_bytes": total,
        "bytes_per_row": round(total / max(rows, 1), 1),
        "heap_bytes_per_row": round(heap / max(rows, 1), 1),
    }


def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--rows", type=int, default=20_000_000, help="other machines' rows")
    ap.add_argument("--machines", type=int, default=200, help="other machines")
    ap.add_argument("--days", type=int, default=20, help="days the other rows span")
    ap.add_argument(
        "--field",
        default="35x23",
        help="field LENGTHxWIDTH in metres (default: seed 001's trial plot)",
    )
    ap.add_argument("--repeat", type=int, default=21)
    ap.add_argument("--keep-db", action="store_true")
    args = ap.parse_args()
    field_m = tuple(float(v) for v in args.field.split("x"))
    assert len(field_m) == 2
    if args.days < 3:
        ap.error("--days must be 3 or more (the retention step drops the oldest day)")

    from fieldrx.db.bootstrap import drop_database
    from fieldrx.db.session import raw_dsn

    os.environ["FIELDRX_MQTT_CREDENTIALS"] = "off"
    print(f"load average at start: {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    url = make_db()
    dsn = raw_dsn(url)
    tmp = Path(tempfile.mkdtemp(prefix="fieldrx-bench-tq-"))
    api = None
    try:
        org, token = make_org(url)
        api, base = start_api(url, env={"FIELDRX_MQTT_CREDENTIALS": "off"})
        job = drive_job(base, token, field_m, tmp)  # type: ignore[arg-type]
        print("baseline (the table holds only the job):")
        base_t = measure(url, base, token, job, args.repeat)
        for k, v in base_t.items():
            print(f"  {k}: p50 {v['p50_ms']} ms, p90 {v['p90_ms']} ms, CPU {v['cpu_ms']} ms/call")
        import psycopg

        with psycopg.connect(dsn) as conn:
            job_day = conn.execute(
                "SELECT floor(extract(epoch FROM first_t) / 86400)::int - 10957"
                " FROM telemetry_job_spans WHERE job_id = %s",
                (job["job_id"],),
            ).fetchone()[0]
        days = list(range(job_day - args.days + 1, job_day + 1))
        print(
            f"loading {args.rows:,} rows of {args.machines} other machines over {args.days} days:"
        )
        load_s = load_others(dsn, org, args.machines, args.rows, days, job_day)
        with psycopg.connect(dsn) as conn:
            n_total = conn.execute("SELECT count(*) FROM telemetry").fetchone()[0]
        print(f"loaded in {load_s:.0f} s; telemetry holds {n_total:,} rows")
        print(f"with {n_total:,} rows:")
        big = measure(url, base, token, job, args.repeat)
        for k, v in big.items():
            print(
                f"  {k}: p50 {v['p50_ms']} ms, p90 {v['p90_ms']} ms, CPU {v['cpu_ms']} ms/call"
                f" (baseline p50 {base_t[k]['p50_ms']}, CPU {base_t[k]['cpu_ms']})"
            )
        print("EXPLAIN, partitions each hot query reads:")
        parts = explain_all(dsn, job)
        ret = retention_drop(dsn, days)
        worst = max(v["p50_ms"] for v in big.values())
        ok = worst <= 100.0 and ret["seconds"] < 1.0
        result = {
            "telemetry_rows": n_total,
            "other_machines": args.machines,
            "days": args.days,
            "job_records": job["n_records"],
            "field_m": args.field,
            "baseline": base_t,
            "with_rows": big,
            "partitions_read": parts,
            "retention_drop_s": round(ret["seconds"], 3),
            "day_partition_bytes_per_row": ret["bytes_per_row"],
            "day_partition_heap_bytes_per_row": ret["heap_bytes_per_row"],
            "loadavg_1m_end": round(os.getloadavg()[0], 1),
            "cpus": os.cpu_count(),
            "retention_rows_dropped": ret["rows"],
            "load_s": round(load_s, 1),
            "worst_p50_ms": worst,
            "pass": ok,
        }
        print(json.dumps(result))
        return 0 if ok else 1
    finally:
        if api is not None:
            api.stop()
        if not args.keep_db:
            drop_database(url)


if __name__ == "__main__":
    sys.exit(main())
