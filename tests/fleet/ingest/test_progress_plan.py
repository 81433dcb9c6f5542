"""Per-cell progress (``ingest.progress.CELL_PROGRESS_CTE``) costs one lookup per cell of a batch.

The statement read each new cell's row before its upsert (``old``) and joined that with
the upsert's result. PostgreSQL inlined ``old`` (referenced once) and, estimating one row
for both sides, ran it again for every upserted cell: n^2 index scans. A thin agent's
cell batch of 200 cells over a job already started took 40,401 scans, 45 ms alone and
about 170 ms under the ingest benchmark's load, more than every other statement of the
thin request together (the thin profile's server CPU). The plan is counted
here (EXPLAIN ANALYZE, rolled back), not timed, so the test cannot be flaky; the counts
the statement returns are checked against their definition as well.
"""

from __future__ import annotations

import json
from typing import Any

import psycopg
from fieldrx.db.session import raw_dsn
from fieldrx.fleet.ingest.progress import (
    CELL_PROGRESS_CTE,
    CELL_UPSERT_SQL,
    cell_progress_params,
)

from tests.fleet.helpers import JobFixture, on_citus

N_CELLS = 300


def _agg(job_id: int, aps: float, seqs: range) -> dict[tuple[int, int], list[Any]]:
    """``cell_progress``'s per-cell sums: one fix per cell at ``aps`` kg/ha applied."""
    return {(job_id, s): [1, 300.0, aps, 1_000_000 + s, 1_000_000 + s] for s in seqs}


def _rows_read(node: dict[str, Any], table: str) -> int:
    """Rows of ``table`` read by the scans of an EXPLAIN (ANALYZE, FORMAT JSON) plan tree:
    per scan node, loops x (rows returned + rows filtered out, both per loop), and at
    least one per loop (an index lookup that finds nothing)."""
    n = 0
    if node.get("Relation Name") == table and "Scan" in node.get("Node Type", ""):
        per_loop = node["Actual Rows"] + node.get("Rows Removed by Filter", 0)
        n += int(node["Actual Loops"]) * max(1, per_loop)
    for child in node.get("Plans", []):
        n += _rows_read(child, table)
    return n


def _run(conn: psycopg.Connection[Any], machine_id: int, agg: dict, explain: bool) -> Any:
    sql = "WITH " + CELL_PROGRESS_CTE + " SELECT id, state, cells_applied, n_cells FROM moved"
    if explain:
        sql = "EXPLAIN (ANALYZE, FORMAT JSON) " + sql
    params = cell_progress_params(machine_id, agg)
    out = conn.execute(sql, params).fetchall()
    if not explain:  # then the sums, as ``ingest.progress.cell_progress`` does
        conn.execute(CELL_UPSERT_SQL, params)
    return out


def test_cell_progress_looks_each_cell_up_once(database_url: str, job: JobFixture) -> None:
    with psycopg.connect(raw_dsn(database_url)) as conn:
        # the job started: half the cells hold records, none with fertilizer yet
        _run(conn, job.machine_id, _agg(job.job_id, 0.0, range(N_CELLS // 2)), False)
        conn.commit()
        # statistics as autovacuum keeps them in production (without them the planner
        # guesses larger tables and hashes: the n^2 plan needs the real, small estimates)
        conn.execute("ANALYZE jobs, job_cells_applied")
        batch = _agg(job.job_id, 250.0, range(N_CELLS))
        # Citus runs the statement as single-shard subplans through the coordinator and
        # has no EXPLAIN ANALYZE for that: there only the counts below are checked
        if not on_citus(conn):
            plan = _run(conn, job.machine_id, batch, True)[0][0]
            root = (plan if isinstance(plan, list) else json.loads(plan))[0]["Plan"]
            conn.rollback()
            read = _rows_read(root, "job_cells_applied")
            # one lookup per cell (the upsert's own arbiter checks are not plan nodes); the
            # inlined join read the table once per upserted cell: ~N_CELLS^2 rows (90,300
            # by index scans with the bench's statistics, 45,000-90,000 by sequential scans
            # here)
            assert read <= 2 * N_CELLS, f"{read} rows of job_cells_applied read, {N_CELLS} cells"
        # the counts: every cell gains fertilizer now (the first half had none)
        moved = _run(conn, job.machine_id, batch, False)
        conn.commit()
        assert [(r[0], r[2]) for r in moved] == [(job.job_id, N_CELLS)]
        # again: the cells are applied already, progress does not move
        assert _run(conn, job.machine_id, batch, False) == []
        conn.commit()
        n, applied = conn.execute(
            "SELECT count(*), count(*) FILTER (WHERE applied_rate_sum > 0)"
            " FROM job_cells_applied WHERE machine_id = %s AND job_id = %s",
            (job.machine_id, job.job_id),
        ).fetchone()
        assert (n, applied) == (N_CELLS, N_CELLS)
