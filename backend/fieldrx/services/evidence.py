"""Evidence is never erased silently: deletions that would cascade to as-applied records.

A machine cascades (foreign keys) to its jobs, a field, plan or prescription too
(``delete_jobs``: no foreign key, see there), and a job to its as-applied records
(``job_cells_applied``, telemetry). Before such a delete the API asks
``unarchived_jobs_with_data``; when any job would
lose as-applied data that was not archived (``job_archives``, see
api/archive.py) the delete is refused with ``Conflict`` naming the jobs.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import text
from sqlalchemy.orm import Session

from fieldrx.errors import Conflict

# the plans and prescriptions whose jobs go with a field / plan, read on the coordinator
_SOURCES = {
    "plan": ("SELECT :id", "SELECT id FROM prescriptions WHERE plan_id = :id"),
    "field": (
        "SELECT id FROM plans WHERE field_id = :id",
        "SELECT r.id FROM prescriptions r JOIN plans p ON p.id = r.plan_id WHERE p.field_id = :id",
    ),
}


def _scope(session: Session, kind: str, obj_id: int) -> tuple[str, dict[str, Any]]:
    """The jobs made from this machine / field / plan / prescription, as a condition on
    ``jobs j`` alone. The plans and prescriptions are read first: past one node ``jobs`` is
    distributed and the coordinator's tables cannot be joined to it in one statement."""
    if kind == "machine":
        return "j.machine_id = :id", {"id": obj_id}
    # The jobs of a field, plan or prescription are on many shards. Citus refuses a write to a
    # coordinator table (the object itself, next) after a multi-shard statement ran on
    # parallel connections in the same transaction; sequential mode runs it on one
    # connection per node. On plain PostgreSQL this only sets an unused placeholder.
    session.execute(text("SET LOCAL citus.multi_shard_modify_mode TO 'sequential'"))
    if kind == "prescription":
        plans, rxs = [], [obj_id]
    else:
        plans_sql, rx_sql = _SOURCES[kind]
        plans = [int(r[0]) for r in session.execute(text(plans_sql), {"id": obj_id})]
        rxs = [int(r[0]) for r in session.execute(text(rx_sql), {"id": obj_id})]
    return "(j.plan_id = ANY(:p) OR j.prescription_id = ANY(:r))", {"p": plans, "r": rxs}


def unarchived_jobs_with_data(session: Session, kind: str, obj_id: int) -> list[int]:
    """Ids of the jobs made from this machine/field/plan/prescription that hold as-applied
    data and have no archive."""
    where, params = _scope(session, kind, obj_id)
    # A machine's subqueries name the machine itself: through ``j.machine_id`` Citus plans
    # the correlated EXISTS on every shard, and after such a multi-shard read it refuses
    # the machine delete's later writes to coordinator tables (tokens, prescriptions).
    machine = ":id" if kind == "machine" else "j.machine_id"
    sql = (
        f"SELECT j.id FROM jobs j WHERE {where}"
        " AND (EXISTS (SELECT 1 FROM job_cells_applied a"
        f"              WHERE a.machine_id = {machine} AND a.job_id = j.id)"
        "      OR EXISTS (SELECT 1 FROM telemetry_job_spans t"
        f"                 WHERE t.machine_id = {machine} AND t.job_id = j.id))"
        " ORDER BY j.id"
    )
    ids = [int(r[0]) for r in session.execute(text(sql), params)]
    if not ids:
        return []
    archived = {
        int(r[0])
        for r in session.execute(
            text("SELECT job_id FROM job_archives WHERE job_id = ANY(:ids)"), {"ids": ids}
        )
    }
    return [i for i in ids if i not in archived]


def delete_jobs(session: Session, kind: str, obj_id: int) -> int:
    """Delete the jobs made from this field / plan / prescription (and with them, by their
    ``(machine_id, job_id)`` foreign keys, their events and per-cell results), inside the
    caller's transaction, before the object itself. Returns how many.

    ``jobs`` has no foreign key to plans or prescriptions (migration 0017): past one node the
    jobs are distributed by machine and Citus refuses a distributed table's foreign key to a
    coordinator table, so the cascade is done here, by the ids read first (``_scope``)."""
    where, params = _scope(session, kind, obj_id)
    res = session.execute(text(f"DELETE FROM jobs j WHERE {where}"), params)
    return int(res.rowcount or 0)  # type: ignore[attr-defined]


def refuse_if_evidence(session: Session, kind: str, obj_id: int) -> None:
    """Raise ``Conflict`` (409) when deleting would erase unarchived as-applied data."""
    jobs = unarchived_jobs_with_data(session, kind, obj_id)
    if jobs:
        shown = ", ".join(str(j) for j in jobs[:20]) + (" ..." if len(jobs) > 20 else "")
        raise Conflict(
            f"{kind} {obj_id} cannot be deleted: job(s) {shown} hold as-applied data that "
            "would be erased; archive them first (POST /api/v1/jobs/{id}/archive)",
            jobs=jobs,
        )
