"""Alembic: upgrade to head and back down to base on an empty database; models match the schema."""

from __future__ import annotations

import uuid

import psycopg
from alembic import command
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from fieldrx.db.bootstrap import alembic_config, drop_database, ensure_database, include_object
from fieldrx.db.models import Base
from sqlalchemy import create_engine

from tests.conftest import PG


def _tables(dsn: str) -> set[str]:
    with psycopg.connect(dsn) as conn:
        rows = conn.execute(
            "SELECT tablename FROM pg_tables WHERE schemaname = 'public'"
        ).fetchall()
    return {r[0] for r in rows}


def test_upgrade_downgrade_roundtrip() -> None:
    name = f"fieldrx_mig_{uuid.uuid4().hex[:8]}"
    url = PG.replace("postgresql://", "postgresql+psycopg://", 1) + f"/{name}"
    dsn = f"{PG}/{name}"
    ensure_database(url)
    try:
        cfg = alembic_config(url)
        command.upgrade(cfg, "head")
        tables = _tables(dsn)
        assert {"fields", "plan_cells", "telemetry", "prescription_rates", "api_tokens"} <= tables
        engine = create_engine(url)
        with engine.connect() as conn:
            ctx = MigrationContext.configure(conn, opts={"include_object": include_object})
            diff = compare_metadata(ctx, Base.metadata)
        engine.dispose()
        assert diff == [], f"models and migrations disagree: {diff}"
        with psycopg.connect(dsn) as conn:  # 0012: procrastinate's queue schema is there
            assert conn.execute("SELECT procrastinate_cancel_job_v1(0, true, false)").fetchone()
        command.downgrade(cfg, "base")
        assert _tables(dsn) <= {"alembic_version", "spatial_ref_sys"}
        with psycopg.connect(dsn) as conn:  # ... and gone with it: functions and types too
            left = conn.execute(
                "SELECT proname FROM pg_proc WHERE proname LIKE 'procrastinate%' UNION ALL "
                "SELECT typname FROM pg_type WHERE typname LIKE 'procrastinate%'"
            ).fetchall()
        assert left == []
        command.upgrade(cfg, "head")
        assert "fields" in _tables(dsn)
    finally:
        drop_database(url)
