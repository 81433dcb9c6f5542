"""The schema and the ingest SQL keep Citus's rules for the distributed layout
(``fieldrx.db.citus``), checked here on plain PostgreSQL: a migrated database's catalog
and the fleet modules' upserts. Each rule was met on a real Citus 13 cluster."""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
import uuid

import fieldrx.fleet
import psycopg
import pytest
from alembic import command
from fieldrx.db.bootstrap import alembic_config, drop_database, ensure_database
from fieldrx.db.citus import NotReady, distribute, do_update_clauses, problems, upsert_problems

from tests.conftest import PG

BEFORE = "0016_rx_products"  # the schema as it was before it was made distributable


def _dsn(url: str) -> str:
    return url.replace("postgresql+psycopg://", "postgresql://", 1)


def test_migrated_schema_keeps_citus_rules(database_url: str) -> None:
    with psycopg.connect(_dsn(database_url)) as conn:
        assert problems(conn) == []


def test_check_finds_what_citus_refused_in_the_old_schema() -> None:
    """The same check on the schema before the change names each refusal met on the
    cluster, and the migration clears every one."""
    name = f"fieldrx_citus_{uuid.uuid4().hex[:8]}"
    url = PG.replace("postgresql://", "postgresql+psycopg://", 1) + f"/{name}"
    ensure_database(url)
    try:
        cfg = alembic_config(url)
        command.upgrade(cfg, BEFORE)
        with psycopg.connect(f"{PG}/{name}") as conn:
            found = "\n".join(problems(conn))
        for expected in (
            "alerts: key alerts_pkey ('id',) lacks the distribution column machine_id",
            "jobs: key jobs_pkey ('id',) lacks the distribution column machine_id",
            "api_tokens: foreign key api_tokens_machine_id_fkey -> machines: a reference"
            " table cannot reference a distributed table",
            "prescriptions: foreign key prescriptions_machine_id_fkey -> machines: a"
            " coordinator table cannot reference a distributed table",
            "job_cells_applied: foreign key job_cells_applied_machine_job_fkey -> jobs has"
            " an ON UPDATE action",
            "jobs: foreign key jobs_plan_id_fkey -> plans: a distributed table can reference"
            " only co-located or reference tables",
            "job_cell_records: foreign key job_cell_records_job_id_fkey -> jobs does not"
            " pair the distribution columns",
        ):
            assert expected in found
        command.upgrade(cfg, "head")
        with psycopg.connect(f"{PG}/{name}") as conn:
            assert problems(conn) == []
        command.downgrade(cfg, BEFORE)  # and back: the old keys return
        with psycopg.connect(f"{PG}/{name}") as conn:
            assert "jobs: key jobs_pkey ('id',)" in "\n".join(problems(conn))
    finally:
        drop_database(url)


def _fleet_sql() -> list[tuple[str, str]]:
    """Every SQL string of the fleet modules and their sub-packages (the ingest path, its
    stages in ``fleet.ingest``): module-level strings and string literals inside functions."""
    out: list[tuple[str, str]] = []
    for info in pkgutil.walk_packages(fieldrx.fleet.__path__, prefix="fieldrx.fleet."):
        mod = importlib.import_module(info.name)
        name = info.name.removeprefix("fieldrx.fleet.")
        out += [(f"{name}.{k}", v) for k, v in vars(mod).items() if isinstance(v, str)]
        tree = ast.parse(inspect.getsource(mod))
        out += [
            (f"{name}:{n.lineno}", n.value)
            for n in ast.walk(tree)
            if isinstance(n, ast.Constant) and isinstance(n.value, str)
        ]
    return out


def test_ingest_upserts_use_only_immutable_functions(database_url: str) -> None:
    sql = [(where, s) for where, s in _fleet_sql() if do_update_clauses(s)]
    assert len({s for _, s in sql}) >= 5  # the stream, status, cell and per-cell upserts
    with psycopg.connect(_dsn(database_url)) as conn:
        bad = [f"{where}: {p}" for where, s in sql for p in upsert_problems(conn, s)]
        assert bad == []
        # the statement as it was: refused on the cluster, so the check must refuse it
        old = (
            "WITH st AS (INSERT INTO cell_record_streams AS s (machine_id, stream) VALUES"
            " (1, 'a') ON CONFLICT (machine_id, stream) DO UPDATE SET acked_seq ="
            " excluded.acked_seq, last_seen_at = now() RETURNING acked_seq),"
            " moved AS (UPDATE jobs SET updated_at = now() WHERE false) SELECT 1"
        )
        assert len(upsert_problems(conn, old)) == 1  # the CTE after it is not an upsert
        assert "now() is not IMMUTABLE" in upsert_problems(conn, old)[0]


def test_distribute_refuses_without_citus(database_url: str) -> None:
    with psycopg.connect(_dsn(database_url), autocommit=True) as conn:
        before = conn.execute("SELECT count(*) FROM pg_constraint").fetchone()
        with pytest.raises(NotReady, match="has no citus extension.*nothing was changed"):
            distribute(conn)
        assert conn.execute("SELECT count(*) FROM pg_constraint").fetchone() == before
