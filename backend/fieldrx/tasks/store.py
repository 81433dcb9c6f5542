"""Task rows: created with their queue job, read by the API, changed by workers.

The API side works in the request's session (``create_tasks``, ``create_batch``,
``request_cancel``: the caller commits). The worker side (``claim``, ``finish_failed``,
``finish_cancelled``, ``is_cancel_requested``) uses short autocommit statements on the
engine; the success of a task is written by the work's own transaction
(``guard`` + ``complete``), never here.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from sqlalchemy import Engine, func, select, text
from sqlalchemy.orm import Session

from fieldrx.db.models import Task
from fieldrx.errors import Invalid, TooMany
from fieldrx.settings import get_settings
from fieldrx.store import driver_connection
from fieldrx.tasks import QUOTA_LOCK_NS, TASK_LOCK_NS
from fieldrx.tasks.kinds import API, Claimed, result_url
from fieldrx.tasks.queue import make_jobs

FINAL = ("succeeded", "failed", "cancelled")


def create_tasks(
    session: Session,
    *,
    organisation_id: int,
    created_by: int | None,
    kind: str,
    params_list: list[dict[str, Any]],
    parent_id: int | None = None,
    message: str = "waiting for a worker",
) -> list[Task]:
    """Insert one task row per params and defer their jobs, in the session's transaction
    (flush only; the caller commits, and a rollback leaves neither rows nor jobs).
    The organisation's quota of open tasks is checked first (``check_quota``)."""
    check_quota(session, organisation_id, len(params_list))
    rows = [
        Task(
            organisation_id=organisation_id,
            created_by=created_by,
            parent_id=parent_id,
            kind=kind,
            status="queued",
            progress=0.0,
            message=message,
            params=params,
        )
        for params in params_list
    ]
    session.add_all(rows)
    session.flush()
    from fieldrx.tasks.queue import get_app

    jobs = get_app().job_manager.batch_defer_jobs(
        make_jobs([(kind, r.id) for r in rows]), connection=driver_connection(session)
    )
    for row, job in zip(rows, jobs, strict=True):
        row.job_id = job.id
    session.flush()
    return rows


QUOTA_RETRY_AFTER_S = 30


def check_quota(session: Session, organisation_id: int, adding: int) -> None:
    """Refuse work that would take the organisation past ``FIELDRX_TASK_QUOTA`` open
    (queued or running) tasks: ``Invalid`` (422) when ``adding`` alone exceeds it, else
    ``TooMany`` (429, retry once some have finished).

    The count is taken under a per-organisation advisory lock held to the end of the
    caller's transaction, so concurrent requests cannot all pass the same count."""
    quota = get_settings().task_quota
    if adding > quota:
        raise Invalid(
            f"{adding} tasks in one request, more than the organisation's quota of {quota} "
            "open tasks (FIELDRX_TASK_QUOTA): split the batch",
            where="field_ids",
        )
    session.execute(
        text("SELECT pg_advisory_xact_lock(:ns, (:org % 2147483647)::int)"),
        {"ns": QUOTA_LOCK_NS, "org": organisation_id},
    )
    open_ = session.scalar(
        select(func.count()).where(
            Task.organisation_id == organisation_id,
            Task.status.in_(("queued", "running")),
            Task.kind.not_like("%\\_batch"),
        )
    )
    if int(open_ or 0) + adding > quota:
        raise TooMany(
            f"the organisation has {open_} tasks queued or running and may have at most "
            f"{quota} (FIELDRX_TASK_QUOTA); {adding} more do not fit: retry once some have "
            "finished, or cancel some",
            retry_after_s=QUOTA_RETRY_AFTER_S,
        )


def create_batch(
    session: Session,
    *,
    organisation_id: int,
    created_by: int | None,
    kind: str,
    params_list: list[dict[str, Any]],
    batch_params: dict[str, Any],
) -> tuple[Task, list[Task]]:
    """A parent row (no job of its own; its state is its children's) and one child task
    per params (flush only)."""
    parent = Task(
        organisation_id=organisation_id,
        created_by=created_by,
        kind=f"{kind}_batch",
        status="queued",
        progress=0.0,
        message=f"{len(params_list)} tasks",
        params=batch_params,
    )
    session.add(parent)
    session.flush()
    children = create_tasks(
        session,
        organisation_id=organisation_id,
        created_by=created_by,
        kind=kind,
        params_list=params_list,
        parent_id=parent.id,
    )
    return parent, children


def _iso(value: dt.datetime | None) -> str | None:
    return value.isoformat() if value else None


def task_item(row: Task) -> dict[str, Any]:
    """One task as the API shows it (a batch's state comes from ``task_view``)."""
    return {
        "id": row.id,
        "kind": row.kind,
        "status": row.status,
        "progress": round(float(row.progress), 4),
        "message": row.message,
        "params": row.params,
        "result": row.result,
        "result_url": result_url(row.kind, row.result),
        "error": row.error,
        "cancel_requested": row.cancel_requested,
        "attempts": row.attempts,
        "parent_id": row.parent_id,
        "created_at": _iso(row.created_at),
        "started_at": _iso(row.started_at),
        "finished_at": _iso(row.finished_at),
        "url": f"{API}/tasks/{row.id}",
    }


def batch_state(counts: dict[str, int], progress_sum: float, cancel: bool) -> tuple[str, float]:
    """A batch's status and progress from its children's: running while any child is not
    final; then failed if any failed, cancelled if any was cancelled, else succeeded."""
    total = sum(counts.values())
    if total == 0:
        return "succeeded", 1.0
    progress = progress_sum / total
    open_ = counts.get("queued", 0) + counts.get("running", 0)
    if open_:
        started = counts.get("running", 0) or total - open_
        return ("running" if started else "queued"), progress
    if counts.get("failed"):
        return "failed", progress
    if counts.get("cancelled") or cancel:
        return "cancelled", progress
    return "succeeded", 1.0


def task_view(session: Session, row: Task, with_children: bool = True) -> dict[str, Any]:
    """``task_item`` plus, for a batch, the children's counts and (``with_children``) items."""
    out = task_item(row)
    if not row.kind.endswith("_batch"):
        return out
    agg = session.execute(
        select(Task.status, func.count(), func.coalesce(func.sum(Task.progress), 0.0))
        .where(Task.parent_id == row.id)
        .group_by(Task.status)
    ).all()
    counts = {s: int(n) for s, n, _ in agg}
    status, progress = batch_state(counts, sum(float(p) for *_, p in agg), row.cancel_requested)
    out.update(status=status, progress=round(progress, 4))
    done = sum(counts.get(s, 0) for s in FINAL)
    out["message"] = f"{done} of {sum(counts.values())} done"
    out["counts"] = {s: counts.get(s, 0) for s in ("queued", "running", *FINAL)}
    if with_children:
        kids = session.scalars(select(Task).where(Task.parent_id == row.id).order_by(Task.id))
        out["items"] = [task_item(k) for k in kids]
    return out


def request_cancel(session: Session, row: Task) -> dict[str, int]:
    """Ask the task (and a batch's children) to stop: queued ones are cancelled at once
    (their jobs too), running ones stop at their next check (within about a second:
    ``services.bounded``) and store nothing. Flush only. Returns counts."""
    from procrastinate import sql

    ids = [row.id]
    if row.kind.endswith("_batch"):
        ids += list(session.scalars(select(Task.id).where(Task.parent_id == row.id)))
    rows = session.scalars(
        select(Task).where(Task.id.in_(ids), Task.status.not_in(FINAL)).with_for_update()
    ).all()
    conn = driver_connection(session)
    cancelled = running = 0
    for t in rows:
        t.cancel_requested = True
        if t.job_id is not None:
            with conn.cursor() as cur:
                cur.execute(
                    sql.queries["cancel_job"],
                    {"job_id": t.job_id, "abort": True, "delete_job": False},
                )
        if t.status == "queued":
            t.status = "cancelled"
            t.message = "cancelled before it started"
            t.finished_at = dt.datetime.now(dt.UTC)
            cancelled += 1
        else:
            running += 1
    row.cancel_requested = True
    session.flush()
    return {"cancelled": cancelled, "stopping": running}


# --- worker side -------------------------------------------------------------------------


def claim(engine: Engine, task_id: int, worker: str) -> Claimed | None:
    """Mark the task running (again, after a dead worker) unless it is final or cancelled;
    a cancelled one is finished as such. None = nothing to do."""
    with engine.begin() as conn:
        row = conn.execute(
            text(
                "UPDATE tasks SET status = 'running', attempts = attempts + 1, worker = :w, "
                "started_at = coalesce(started_at, clock_timestamp()), "
                "updated_at = clock_timestamp(), "
                "message = CASE WHEN attempts > 0 THEN 'restarted after a worker stopped' "
                "ELSE 'started' END "
                "WHERE id = :id AND status IN ('queued', 'running') AND NOT cancel_requested "
                "RETURNING kind, params, organisation_id, created_by, attempts"
            ),
            {"id": task_id, "w": worker[:200]},
        ).first()
        if row is None:
            conn.execute(
                text(
                    "UPDATE tasks SET status = 'cancelled', finished_at = clock_timestamp(), "
                    "updated_at = clock_timestamp(), message = 'cancelled' "
                    "WHERE id = :id AND cancel_requested AND status IN ('queued', 'running')"
                ),
                {"id": task_id},
            )
            return None
    return Claimed(task_id, row[0], dict(row[1]), int(row[2]), row[3], int(row[4]))


def is_cancel_requested(engine: Engine, task_id: int) -> bool:
    with engine.connect() as conn:
        return bool(
            conn.execute(
                text("SELECT cancel_requested FROM tasks WHERE id = :id"), {"id": task_id}
            ).scalar()
        )


def _finish(engine: Engine, task_id: int, status: str, message: str, error: str | None) -> None:
    with engine.begin() as conn:
        conn.execute(
            text(
                "UPDATE tasks SET status = :s, message = :m, error = :e, "
                "finished_at = clock_timestamp(), "
                "updated_at = clock_timestamp() WHERE id = :id AND status NOT IN "
                "('succeeded', 'failed', 'cancelled')"
            ),
            {"id": task_id, "s": status, "m": message, "e": error},
        )


def finish_failed(engine: Engine, task_id: int, error: str) -> None:
    _finish(engine, task_id, "failed", "failed", error)


def finish_cancelled(engine: Engine, task_id: int) -> None:
    _finish(engine, task_id, "cancelled", "cancelled; nothing was stored", None)


def guard(session: Session, task_id: int) -> dict[str, Any] | None:
    """First statement of a work transaction: wait for any other run of this task to end
    (advisory lock), then return its stored result if it already succeeded (the caller
    stores nothing and returns it)."""
    session.execute(
        text("SELECT pg_advisory_xact_lock(:ns, (:id % 2147483647)::int)"),
        {"ns": TASK_LOCK_NS, "id": task_id},
    )
    row = session.execute(
        text("SELECT status, result FROM tasks WHERE id = :id"), {"id": task_id}
    ).first()
    if row is not None and row[0] == "succeeded":
        return dict(row[1] or {})
    return None


def complete(session: Session, task_id: int, result: dict[str, Any], message: str) -> bool:
    """Last statement of a work transaction: the task succeeded with ``result``. False when
    it is no longer running (another run got there first, or it failed): then the caller
    must roll back.

    Times are ``clock_timestamp()``, the moment of the statement: PostgreSQL's ``now()`` is
    the transaction's start, which for this statement is when the work began, so a task
    that ran for minutes showed started and finished milliseconds apart."""
    import json

    done = session.execute(
        text(
            "UPDATE tasks SET status = 'succeeded', progress = 1, message = :m, "
            "result = CAST(:r AS jsonb), error = NULL, finished_at = clock_timestamp(), "
            "updated_at = clock_timestamp() "
            "WHERE id = :id AND status = 'running'"
        ),
        {"id": task_id, "r": json.dumps(result), "m": message},
    )
    return bool(done.rowcount)  # type: ignore[attr-defined]
