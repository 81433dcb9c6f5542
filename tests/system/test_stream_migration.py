"""Revision 0004 on a database with telemetry: what was stored becomes each machine's legacy
stream '' with its acknowledged seq, so format 1 agents go on where they were."""

from __future__ import annotations

import uuid

import psycopg
from alembic import command
from fieldrx.db.bootstrap import alembic_config, drop_database, ensure_database

from tests.conftest import PG


def test_0004_moves_stored_telemetry_to_the_legacy_stream() -> None:
    name = f"fieldrx_mig_{uuid.uuid4().hex[:8]}"
    url = PG.replace("postgresql://", "postgresql+psycopg://", 1) + f"/{name}"
    dsn = f"{PG}/{name}"
    ensure_database(url)
    try:
        cfg = alembic_config(url)
        command.upgrade(cfg, "0003_telemetry_geom_nullable")
        with psycopg.connect(dsn, autocommit=True) as conn:
            conn.execute("INSERT INTO organisations (id, name) VALUES (1, 'o')")
            conn.execute(
                "INSERT INTO machines (id, organisation_id, name, implement_type, width_m, lag_s,"
                " calibration, controller, antenna_forward_m, antenna_lateral_m, speed_min_m_s,"
                " speed_max_m_s) VALUES (1, 1, 'm', 'spreader', 2.3, 1.5, '{}', '{}', 0, 0, 1, 2)"
            )
            conn.execute(
                "INSERT INTO telemetry (machine_id, seq, t, fix_quality, implement_down, alarms,"
                " queue_backlog) SELECT 1, s, to_timestamp(1790000000 + s), 4, true, '{}', 0"
                " FROM generate_series(1, 7) s"
            )
            conn.execute(
                "INSERT INTO machine_status (machine_id, last_seen_at, acked_seq, queue_backlog,"
                " alarms) VALUES (1, now(), 7, 0, '{}')"
            )
        command.upgrade(cfg, "0004_telemetry_streams")
        with psycopg.connect(dsn, autocommit=True) as conn:
            assert conn.execute(
                "SELECT stream, first_seq, acked_seq, n_records,"
                " extract(epoch FROM first_t)::int, extract(epoch FROM last_t)::int"
                " FROM telemetry_streams"
            ).fetchall() == [("", 1, 7, 7, 1790000001, 1790000007)]
            assert conn.execute("SELECT DISTINCT stream FROM telemetry").fetchall() == [("",)]
            conn.execute(
                "INSERT INTO telemetry (machine_id, stream, seq, t, fix_quality, implement_down,"
                " alarms, queue_backlog) VALUES (1, 'abc', 1, now(), 4, true, '{}', 0)"
            )  # the same seq on another stream is another record
        command.downgrade(cfg, "0003_telemetry_geom_nullable")
        with psycopg.connect(dsn, autocommit=True) as conn:
            assert conn.execute("SELECT count(*) FROM telemetry").fetchone() == (7,)
    finally:
        drop_database(url)
