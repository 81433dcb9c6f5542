"""Revision 0010 on a database with telemetry: every row written before the partitioning
is there after it (and after a downgrade), each day in its own partition, and ingest
still deduplicates a resend of stored records and hears a reused seq."""

from __future__ import annotations

import uuid

import psycopg
from alembic import command
from fieldrx.db.bootstrap import alembic_config, drop_database, ensure_database
from fieldrx.fleet.ingest.pipeline import ingest

from tests.conftest import PG

T0 = 1_780_000_000  # 2026-05-28 20:26:40 UTC
# every column, as text, in a stable order: the rows must come back identical
ROWS_SQL = (
    "SELECT md5(string_agg(r::text, '|' ORDER BY machine_id, stream, seq)), count(*)"
    " FROM telemetry r"
)


def _wire(machine_id: int, seq: int, t: float) -> dict[str, object]:
    return {
        "machine_id": machine_id, "seq": seq, "t": t, "lon": 11.5 + seq * 1e-6, "lat": 48.1,
        "fix_quality": 4, "hdop": 0.9, "speed_raw_m_s": 2.0, "speed_filtered_m_s": 2.0,
        "heading_deg": 90.0, "job_id": 7, "cell_seq": seq % 50, "target_rate_kg_ha": 200.0,
        "applied_rate_kg_ha": 198.0, "target_shaft_rpm": 30.0, "actual_shaft_rpm": 29.8,
        "duty": 40.0, "ndvi": None, "depth_mm": None, "implement_down": True, "alarms": [],
        "queue_backlog": 0, "fix_period_s": 0.1,
    }  # fmt: skip


def test_0010_keeps_every_row_and_dedup() -> None:
    name = f"fieldrx_mig_{uuid.uuid4().hex[:8]}"
    url = PG.replace("postgresql://", "postgresql+psycopg://", 1) + f"/{name}"
    dsn = f"{PG}/{name}"
    ensure_database(url)
    try:
        cfg = alembic_config(url)
        command.upgrade(cfg, "0009_job_kinds")
        with psycopg.connect(dsn, autocommit=True) as conn:
            conn.execute("INSERT INTO organisations (id, name) VALUES (1, 'o')")
            for m in (1, 2, 3):
                conn.execute(
                    "INSERT INTO machines (id, organisation_id, name, implement_type, width_m,"
                    " lag_s, calibration, controller, antenna_forward_m, antenna_lateral_m,"
                    " speed_min_m_s, speed_max_m_s) VALUES"
                    " (%s, 1, 'm', 'spreader', 2.3, 1.5, '{}', '{}', 0, 0, 1, 2)",
                    (m,),
                )
            # 3 machines x 2 streams x 12 days x 500 records (one every 6 min across 2 days
            # per stream, days apart); machine 3's legacy stream '' has no job
            conn.execute(
                "INSERT INTO telemetry (machine_id, stream, seq, t, job_id, geom, fix_quality,"
                " hdop, speed_raw_m_s, cell_seq, applied_rate_kg_ha, implement_down, alarms,"
                " queue_backlog, fix_period_s, ndvi_raw)"
                " SELECT m, st, s, to_timestamp(%s + d * 86400 + s * 30 + m),"
                "  CASE WHEN m = 3 AND st = '' THEN NULL ELSE 7 END,"
                "  ST_SetSRID(ST_MakePoint(11.5 + s * 1e-6, 48.1), 4326), 4, 0.9, 2.0, s %% 50,"
                "  198.0 + m, true,"
                "  CASE WHEN s %% 97 = 0 THEN '{no_fix}' ELSE '{}' END::varchar[], 0, 0.1,"
                "  CASE WHEN s %% 2 = 0 THEN 0.5 END"
                " FROM generate_series(1, 3) m, unnest(ARRAY['', 'abc']) st,"
                "  generate_series(0, 11) d, generate_series(d * 500 + 1, d * 500 + 500) s",
                (T0,),
            )
            conn.execute(
                "INSERT INTO telemetry_streams (machine_id, stream, first_seq, acked_seq,"
                " n_records, first_t, last_t)"
                " SELECT machine_id, stream, 1, max(seq), count(*), min(t), max(t)"
                " FROM telemetry GROUP BY machine_id, stream"
            )
            before = conn.execute(ROWS_SQL).fetchone()
            days = conn.execute(
                "SELECT count(DISTINCT date_trunc('day', t AT TIME ZONE 'UTC')) FROM telemetry"
            ).fetchone()[0]
        assert before[1] == 3 * 2 * 12 * 500
        command.upgrade(cfg, "head")
        with psycopg.connect(dsn, autocommit=True) as conn:
            assert conn.execute(ROWS_SQL).fetchone() == before
            per = conn.execute(
                "SELECT tableoid::regclass::text, count(*) FROM telemetry GROUP BY 1"
            ).fetchall()
            assert len(per) == days and "telemetry_default" not in dict(per)
            assert conn.execute(
                "SELECT relkind FROM pg_class WHERE relname = 'telemetry'"
            ).fetchone() == ("p",)
            assert conn.execute(
                "SELECT max_seq FROM telemetry_streams WHERE machine_id = 2 AND stream = 'abc'"
            ).fetchone() == (6000,)
            assert conn.execute(
                "SELECT machine_id, job_id, n_records FROM telemetry_job_spans ORDER BY machine_id"
            ).fetchall() == [(1, 7, 12000), (2, 7, 12000), (3, 7, 6000)]
        with psycopg.connect(dsn) as conn:
            # a resend of stored records: duplicates, nothing stored twice
            t5 = conn.execute(
                "SELECT extract(epoch FROM t)::float8 FROM telemetry"
                " WHERE machine_id = 2 AND stream = 'abc' AND seq BETWEEN 4001 AND 4010"
                " ORDER BY seq"
            ).fetchall()
            resend = [_wire(2, 4001 + i, t) for i, (t,) in enumerate(t5)]
            r = ingest(conn, 2, resend, "abc", 1, True)
            assert (r.stored, r.duplicates, r.acked_seq, r.stream_conflict) == (0, 10, 6000, False)
            # the same seqs holding other records (a restored queue): heard, not stored
            r = ingest(conn, 2, [_wire(2, 4001 + i, T0 + 50 * 86400.0 + i) for i in range(5)],
                       "abc", 1, True)  # fmt: skip
            assert r.stream_conflict and r.stored == 0
            # new records after the stored ones go on
            r = ingest(conn, 2, [_wire(2, 6001 + i, T0 + 12 * 86400.0 + i) for i in range(5)],
                       "abc", 1, True)  # fmt: skip
            assert (r.stored, r.acked_seq) == (5, 6005)
            assert conn.execute("SELECT count(*) FROM telemetry").fetchone() == (36005,)
        command.downgrade(cfg, "0009_job_kinds")
        with psycopg.connect(dsn, autocommit=True) as conn:
            assert (
                conn.execute(ROWS_SQL + " WHERE NOT (machine_id = 2 AND seq > 6000)").fetchone()
                == before
            )
            assert conn.execute("SELECT count(*) FROM telemetry").fetchone() == (36005,)
            assert conn.execute(
                "SELECT relkind FROM pg_class WHERE relname = 'telemetry'"
            ).fetchone() == ("r",)
        command.upgrade(cfg, "head")
        with psycopg.connect(dsn, autocommit=True) as conn:
            assert conn.execute("SELECT count(*) FROM telemetry").fetchone() == (36005,)
    finally:
        drop_database(url)
