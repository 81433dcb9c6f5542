"""Every ingest and job-state statement names its machine in every distributed table it
touches, so that past one node (Citus, docs/scale.md section 2) it is a router plan on one
shard.

The statements are captured as they run (a recording psycopg cursor for the ingest lanes,
a SQLAlchemy cursor event for the ORM's state change) and read: on plain PostgreSQL the
text is checked (each distributed table in a FROM / JOIN / UPDATE names its distribution
column, each INSERT lists it); on a Citus coordinator each statement's EXPLAIN must also be
one task with no distributed subplan. The ORM's ``UPDATE jobs ... WHERE jobs.id = ?``
named only the id and ran on every shard.
"""

from __future__ import annotations

import re
import time
from typing import Any

import psycopg
from fieldrx.db.citus import DISTRIBUTED
from fieldrx.db.models import Job
from fieldrx.db.session import make_engine, raw_dsn
from fieldrx.fleet.cellrecords import ingest_cells
from fieldrx.fleet.ingest.pipeline import ingest
from fieldrx.fleet.jobstate import change_state, lock_job
from sqlalchemy import event
from sqlalchemy.orm import Session

from tests.fleet.helpers import JobFixture, record

_REF = re.compile(r"\b(FROM|JOIN|UPDATE|INTO)\s+(?:ONLY\s+)?(\w+)(?:\s+(?:AS\s+)?(\w+))?", re.I)
_NOT_ALIAS = {
    "where", "set", "on", "join", "left", "inner", "group", "order", "limit", "using",
    "returning", "for", "values", "select", "union", "as", "default", "cross", "lateral",
}  # fmt: skip


def unrouted(sql: str) -> list[str]:
    """The distributed tables ``sql`` reads or writes without naming their distribution
    column (``alias.col =`` / ``col =`` / an INSERT's column list)."""
    missing = []
    for m in _REF.finditer(sql):
        verb, table, alias = m.group(1).upper(), m.group(2).lower(), (m.group(3) or "")
        col = DISTRIBUTED.get(table)
        if col is None:
            continue
        if verb == "INTO":
            cols = re.match(r"\s*(?:AS\s+\w+\s*)?\(([^)]*)\)", sql[m.end(2) :], re.I)
            if cols is None or col not in re.split(r"[\s,]+", cols.group(1)):
                missing.append(f"INSERT INTO {table} without {col}")
            continue
        name = table if not alias or alias.lower() in _NOT_ALIAS else alias
        named = re.search(rf"\b{re.escape(name)}\.{col}\s*=", sql) or (
            name == table and re.search(rf"(?<![.\w]){col}\s*=", sql)
        )
        if not named:
            missing.append(f"{verb} {table} {alias} without {name}.{col}")
    return missing


class _Recorder(psycopg.Cursor[Any]):
    seen: list[tuple[str, Any]] = []

    def execute(self, query: Any, params: Any = None, **kw: Any) -> Any:  # type: ignore[override]
        _Recorder.seen.append((str(query), params))
        return super().execute(query, params, **kw)


def _citus(conn: psycopg.Connection[Any]) -> bool:
    row = conn.execute("SELECT count(*) FROM pg_extension WHERE extname = 'citus'").fetchone()
    return bool(row and row[0])


def _router(conn: psycopg.Connection[Any], sql: str, params: Any) -> str | None:
    """On a Citus coordinator: None when ``sql`` is one task without subplans, else its plan."""
    with conn.transaction(force_rollback=True):
        plan = "\n".join(r[0] for r in conn.execute("EXPLAIN " + sql, params).fetchall())
    if "Custom Scan (Citus" not in plan:
        return None  # not distributed: a coordinator-only statement
    if "Distributed Subplan" in plan or "Task Count: 1\n" not in plan + "\n":
        return plan
    return None


def _cell(job: JobFixture, seq: int, cell: int, t: float) -> dict[str, Any]:
    return {
        "machine_id": job.machine_id, "seq": seq, "job_id": job.job_id, "cell_seq": cell,
        "t_entry": t, "t_exit": t + 1.5, "n_fixes": 15, "worked_s": 1.5, "mass_g": 10.0,
        "driven_m": 5.0, "mean_speed_m_s": 1.8, "mean_target_rate_kg_ha": 300.0,
        "mean_applied_rate_kg_ha": 298.0, "flags": [],
    }  # fmt: skip


def test_ingest_and_state_statements_name_the_machine(
    db,
    job: JobFixture,
    database_url: str,  # noqa: ANN001
) -> None:
    _Recorder.seen = []
    t = time.time() - 300
    with psycopg.connect(raw_dsn(database_url), cursor_factory=_Recorder) as conn:
        recs = [record(job, s, t=t + s, cell=(s - 1) % 8) for s in range(1, 41)]
        assert ingest(conn, job.machine_id, recs, "wide", 1, True).stored == 40
        cells = [_cell(job, s, (s - 1) % 8, t + 2 * s) for s in range(1, 11)]
        assert ingest_cells(conn, job.machine_id, cells, "thin", 1).stored == 10
    lanes = [(q, p) for q, p in _Recorder.seen if not q.lstrip().upper().startswith("COPY")]
    assert any("job_cells_applied" in q for q, _ in lanes)  # the per-cell statements ran

    orm: list[tuple[str, Any]] = []
    eng = make_engine(database_url)

    @event.listens_for(eng, "before_cursor_execute")
    def _seen(conn: Any, cur: Any, sql: str, params: Any, ctx: Any, many: bool) -> None:
        orm.append((sql, params))

    try:
        with Session(eng) as s:
            j = s.get(Job, job.job_id)
            assert j is not None
            for state in ("paused", "running", "paused", "running"):
                lock_job(s, j)
                assert change_state(s, j, state)
                s.commit()
            s.delete(s.get(Job, job.job_id))
            s.flush()
            s.rollback()
    finally:
        eng.dispose()
    job_writes = ("UPDATE JOBS", "DELETE FROM JOBS")
    updates = [(q, p) for q, p in orm if q.lstrip().upper().startswith(job_writes)]
    assert len(updates) >= 5, orm

    # the ORM's writes and the row lock (a lookup by the job's id alone, ``session.get``,
    # is a read by a globally unique key: correct anywhere, left to the caller)
    writes = [
        (q, p)
        for q, p in orm
        if q.lstrip().upper().startswith(("UPDATE", "DELETE", "INSERT")) or "FOR UPDATE" in q
    ]
    statements = lanes + writes
    bad = {q: unrouted(q) for q, _ in statements if unrouted(q)}
    assert not bad, bad
    with psycopg.connect(raw_dsn(database_url)) as conn:
        if _citus(conn):
            dml = ("SELECT", "INSERT", "UPDATE", "DELETE", "WITH")
            plans = {
                q: _router(conn, q, p)
                for q, p in statements
                if q.lstrip().upper().startswith(dml)
                and not q.lstrip().upper().startswith("SELECT PG_")
            }
            assert not any(plans.values()), {q: p for q, p in plans.items() if p}


def test_the_check_sees_a_statement_by_id_alone() -> None:
    assert unrouted("UPDATE jobs SET state=%(state)s WHERE jobs.id = %(jobs_id)s")
    assert not unrouted(
        "UPDATE jobs SET state=%(s)s WHERE jobs.id = %(i)s AND jobs.machine_id = %(m)s"
    )
    assert unrouted(
        "SELECT 1 FROM jobs j JOIN job_events e ON e.job_id = j.id WHERE j.machine_id = 1"
    )
    assert unrouted("INSERT INTO alerts (id, kind) VALUES (1, 'x')")
    assert not unrouted("INSERT INTO alerts AS a (machine_id, kind) VALUES (1, 'x')")
