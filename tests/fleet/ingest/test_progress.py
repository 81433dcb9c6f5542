"""The progress stage: per-cell sums of the records that count, and the statements that
add them and move the jobs' progress."""

from __future__ import annotations

import json

from fieldrx.fleet.ingest.progress import (
    CELL_UPSERT_SQL,
    PROGRESS_BY_WORK,
    cell_progress,
    cell_progress_params,
    cell_sums,
)

from tests.fleet.ingest.cursor import ScriptedCursor
from tests.fleet.ingest.rows import M, rows


def test_only_implement_down_records_in_a_jobs_cell_count() -> None:
    counted = rows(10, 11, 12, applied_rate_kg_ha=90.0)  # cell 1
    up = rows(13, implement_down=False)
    no_job = rows(14, job_id=None)
    no_cell = rows(15, cell_seq=None)
    sums = cell_sums([counted[2], *up, *no_job, *no_cell, counted[0], counted[1]])
    assert list(sums) == [(3, 1)]
    n, target, applied, first, last = sums[(3, 1)]
    assert (n, target, applied) == (3, 300.0, 270.0)
    assert (first, last) == (counted[0].t, counted[2].t)


def test_nothing_to_count_runs_no_statement() -> None:
    cur = ScriptedCursor()
    assert cell_progress(cur, M, 1, {}) == [] and cur.executed == []


def test_progress_reads_before_the_sums_are_added() -> None:
    sums = cell_sums(rows(10, 20))
    cur = ScriptedCursor([(3, "running", 2, 8)])
    msgs = cell_progress(cur, M, 1, sums)
    (progress_sql, params), (upsert_sql, upsert_params) = cur.executed
    assert progress_sql.startswith("WITH") and upsert_sql == CELL_UPSERT_SQL
    assert params is upsert_params
    assert [(m["job_id"], m["progress"]) for m in msgs] == [(3, 0.25)]


def test_the_parameters_name_the_machine_and_the_kinds_counted_by_work() -> None:
    params = cell_progress_params(M, {(3, 1): [2, 200.0, 190.0, 10, 20]})
    assert params["m"] == M and params["kinds"] == list(PROGRESS_BY_WORK)
    assert json.loads(params["cells"]) == [
        {"job_id": 3, "seq": 1, "n": 2, "ts": 200.0, "aps": 190.0, "ft": 10, "lt": 20}
    ]
