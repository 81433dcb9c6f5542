"""Ingest stage 5, progress: per-cell sums of the machine's jobs and the jobs' progress.

Only records with a job, a cell and the implement down count. When a cell counts as done
(``jobs.cells_applied``) depends on the job's kind: a prescription-map job (seed 001) once
the cell has received a positive applied rate; a sensor kind (``PROGRESS_BY_WORK``: seed
000 topdressing, seed 002 seeding) once the implement has worked in it, i.e. its first
implement-down record -- a seeding job reports no fertilizer rate at all and stayed at
0 %, and a topdressing cell whose sensor said "no fertilizer" has still been driven. The
thin profile's cell records (``fleet.cellrecords``) move progress through the same
``cell_progress``.
"""

from __future__ import annotations

from typing import Any

import orjson
import psycopg
from fieldrx_edge.jobkinds.registry import kinds

from fieldrx.fleet.ingest.live import job_messages
from fieldrx.fleet.telemetry_row import TelemetryRow

# job kinds whose progress counts the cells the implement worked in, not the cells that got
# a positive applied rate (the registry's ``progress == "work"``: seed 000 topdressing, seed
# 002 seeding): see the module's doc
PROGRESS_BY_WORK = tuple(k.name for k in kinds() if k.progress == "work")

# (job, cell) -> [records, target rate sum, applied rate sum, first t, last t]
CellSums = dict[tuple[int, int], list[Any]]


def cell_sums(new: list[TelemetryRow]) -> CellSums:
    """The batch's records that count, summed per (job, cell); times as COPY microseconds."""
    agg: CellSums = {}
    for r in new:
        if r.job_id is None or r.cell_seq is None or not r.implement_down:
            continue
        key = (r.job_id, r.cell_seq)
        a = agg.get(key)
        tr = r.target_rate_kg_ha or 0.0
        ar = r.applied_rate_kg_ha or 0.0
        if a is None:
            agg[key] = [1, tr, ar, r.t, r.t]
        else:
            a[0] += 1
            a[1] += tr
            a[2] += ar
            if r.t < a[3]:
                a[3] = r.t
            if r.t > a[4]:
                a[4] = r.t
    return agg


def cell_progress(
    cur: psycopg.Cursor[Any], machine_id: int, org: int, agg: CellSums
) -> list[dict[str, Any]]:
    """Add per-cell sums ((job, cell) -> [records, target rate sum, applied rate sum,
    first t, last t], times as COPY microseconds) of this machine's jobs to
    ``job_cells_applied`` and move job progress (the module's doc for the rules); the job
    messages for the live view. Two statements, each a single-shard router plan on Citus
    (docs/scale.md section 2): Citus router-plans common table expressions that read or
    UPDATE, never one that INSERTs, so the upsert of the sums is its own statement."""
    if not agg:
        return []
    params = cell_progress_params(machine_id, agg)
    # progress first: it reads the cells' rows before this batch's sums are added (the
    # batch's machine is locked, so nothing else writes them in between)
    cur.execute(
        "WITH " + CELL_PROGRESS_CTE + " SELECT id, state, cells_applied, n_cells FROM moved",
        params,
    )
    moved = cur.fetchall()
    cur.execute(CELL_UPSERT_SQL, params)
    return job_messages(machine_id, org, moved)


# ``cell_progress`` as common table expressions (parameters: ``cell_progress_params``); the
# last one, ``moved``, returns the jobs whose progress moved (id, state, cells_applied,
# n_cells): ``job_messages``
CELL_PROGRESS_CTE = """
    new AS (
        -- one JSON parameter, parsed once (arrays are dumped element by element in Python)
        SELECT n.job_id, n.seq, n.n, n.ts, n.aps,
            timestamptz '2000-01-01 00:00:00+00' + n.ft * interval '1 microsecond' AS ft,
            timestamptz '2000-01-01 00:00:00+00' + n.lt * interval '1 microsecond' AS lt
        FROM json_to_recordset(%(cells)s::json)
            AS n(job_id int, seq int, n int, ts float8, aps float8, ft int8, lt int8)
        -- this machine's jobs
        WHERE n.job_id IN (SELECT id FROM jobs WHERE machine_id = %(m)s)
    ), old AS MATERIALIZED (
        -- each new cell's row before this batch's sums (``CELL_UPSERT_SQL`` runs next),
        -- looked up once per new cell; materialised, with ``gained`` reading only this:
        -- inlined into a join with the upsert (the planner estimates one row for both)
        -- it was re-run per upserted cell, n^2 index scans (a 200-cell batch of the thin
        -- profile: 40,401, 45-170 ms; tests/fleet/ingest/test_progress_plan.py)
        SELECT n.job_id, n.aps, c.seq IS NOT NULL AS existed,
            coalesce(c.applied_rate_sum, 0) AS before_aps
        FROM new n LEFT JOIN job_cells_applied c
            ON c.machine_id = %(m)s AND c.job_id = n.job_id AND c.seq = n.seq
    ), gained AS (
        -- every new cell is then upserted (inserted, or updated: its sum becomes
        -- before + aps, the same float8 sum as ``CELL_UPSERT_SQL``'s), so the counts
        -- follow from ``old``
        SELECT job_id,
            count(*) FILTER (WHERE NOT existed) AS worked,  -- first record in the cell
            count(*) FILTER (WHERE before_aps + aps > 0 AND before_aps <= 0) AS applied
        FROM old
        GROUP BY job_id
    ), moved AS (
        UPDATE jobs j SET cells_applied = j.cells_applied + g.k, updated_at = now()
        FROM (SELECT g.job_id, CASE WHEN jk.kind = ANY(%(kinds)s::text[]) THEN g.worked
                                    ELSE g.applied END AS k
              FROM gained g JOIN jobs jk ON jk.machine_id = %(m)s AND jk.id = g.job_id) g
        WHERE j.machine_id = %(m)s AND j.id = g.job_id AND g.k > 0
        RETURNING j.id, j.state, j.cells_applied, j.n_cells
    )
"""


# ``cell_progress``'s sums added to ``job_cells_applied``, after ``CELL_PROGRESS_CTE`` read
# the rows before them. The batch's cells join their jobs on this machine: on Citus an
# INSERT ... SELECT that reads a co-located table by its distribution column is pushed down
# to the machine's shard (from the JSON alone it is pulled through the coordinator)
CELL_UPSERT_SQL = """
    INSERT INTO job_cells_applied AS c (machine_id, job_id, seq, n_records,
        target_rate_sum, applied_rate_sum, first_t, last_t)
    SELECT j.machine_id, n.job_id, n.seq, n.n, n.ts, n.aps,
        timestamptz '2000-01-01 00:00:00+00' + n.ft * interval '1 microsecond',
        timestamptz '2000-01-01 00:00:00+00' + n.lt * interval '1 microsecond'
    FROM json_to_recordset(%(cells)s::json)
        AS n(job_id int, seq int, n int, ts float8, aps float8, ft int8, lt int8)
    JOIN jobs j ON j.machine_id = %(m)s AND j.id = n.job_id
    ON CONFLICT (machine_id, job_id, seq) DO UPDATE SET
        n_records = c.n_records + excluded.n_records,
        target_rate_sum = c.target_rate_sum + excluded.target_rate_sum,
        applied_rate_sum = c.applied_rate_sum + excluded.applied_rate_sum,
        first_t = least(c.first_t, excluded.first_t),
        last_t = greatest(c.last_t, excluded.last_t)
"""


def cell_progress_params(machine_id: int, agg: CellSums) -> dict[str, Any]:
    """``CELL_PROGRESS_CTE``'s parameters for these per-cell sums (``cell_progress``)."""
    return {
        "cells": orjson.dumps(
            [
                {"job_id": j, "seq": c, "n": n, "ts": ts, "aps": aps, "ft": ft, "lt": lt}
                for (j, c), (n, ts, aps, ft, lt) in agg.items()
            ]
        ).decode(),
        "m": machine_id,
        "kinds": list(PROGRESS_BY_WORK),
    }
