"""What each kind of task does, and how a worker runs it.

``execute`` runs in a worker thread of ``fieldrx worker``: it claims the task row, runs
the kind's work and records a failure or a cancellation. The work itself:

- ``plan`` and ``prescription`` run in a child process of ``services.bounded`` (the same
  forkserver, time limit and kill-on-cancel as the inline API), whose one transaction
  stores the result and completes the task under ``store.guard`` (exactly once);
- ``export`` and ``report`` run in the worker thread (``tasks.exports``) and store their
  file with the task's success (``tasks.files``);
- ``imagery`` runs ``imagery.ingest.ingest`` (its own spawned converter with a time limit:
  GDAL state must not be forked) and records the row + completes the task in one
  transaction in the worker thread.

Progress is written by ``Progress`` on a connection of its own (autocommit), so the API
sees it while the work's transaction is still open; it also answers a cancellation by
raising ``Cancelled`` at the next stage (cooperative), while ``should_stop`` lets the
parent kill the child between stages (forced, within about a second).
"""

from __future__ import annotations

import logging
import os
import socket
from collections.abc import Callable
from typing import Any

from sqlalchemy.orm import Session

from fieldrx.db.models import Field, Machine, Plan
from fieldrx.db.session import get_engine, raw_dsn
from fieldrx.errors import Cancelled
from fieldrx.settings import get_settings

# exports, imports: importing them registers their kinds, so importing this module (the
# worker, the API's task routes, fieldrx migrate) fills the whole registry
from fieldrx.tasks import exports, imports, store  # noqa: F401
from fieldrx.tasks.context import (
    Progress,
    StopFn,
    TaskInputError,
    in_transaction,
    incoming_upload,
    is_user_error,
)
from fieldrx.tasks.kinds import TASK_KINDS, TaskKind

log = logging.getLogger(__name__)


def _scoped(session: Session, model: type[Any], obj_id: Any, org: int, what: str) -> Any:
    obj = session.get(model, int(obj_id)) if obj_id is not None else None
    if obj is None or obj.organisation_id != org:
        raise TaskInputError(f"{what} {obj_id} not found (deleted after the task was queued?)")
    return obj


def _plan_work(
    session: Session, params: dict[str, Any], org: int, user: int | None, progress: Progress
) -> tuple[dict[str, Any], str]:
    from fieldrx.services.plans import PlanParams, create_plan

    field = _scoped(session, Field, params.get("field_id"), org, "field")
    plan = create_plan(session, field, PlanParams(**params["plan"]), org, progress=progress)
    result = {"plan_id": int(plan.id), "field_id": int(field.id), "n_cells": int(plan.n_cells)}
    return result, f"planned {plan.n_cells:,} cells"


def plan_child(database_url: str, task_id: int, time_limit_s: float) -> dict[str, Any]:
    """A plan task in a ``services.bounded`` child: plan, store, complete (one transaction)."""
    return in_transaction(database_url, task_id, time_limit_s, _plan_work)


def _rx_work(
    session: Session, params: dict[str, Any], org: int, user: int | None, progress: Progress
) -> tuple[dict[str, Any], str]:
    from fieldrx.services.prescriptions import create as svc

    b = params["body"]
    plan = _scoped(session, Plan, params.get("plan_id"), org, "plan")
    field = _scoped(session, Field, plan.field_id, org, "field")
    machine = None
    if b.get("machine_id") is not None:
        machine = _scoped(session, Machine, b["machine_id"], org, "machine")
    progress(0.1, "loading cells and data")
    rx = svc.create_from_request(
        session, plan, field, machine, b, organisation_id=org, user_id=user
    )
    progress(0.95, "stored")
    return {"prescription_id": int(rx.id), "plan_id": int(plan.id)}, "prescription built"


def prescription_child(database_url: str, task_id: int, time_limit_s: float) -> dict[str, Any]:
    """A prescription task in a ``services.bounded`` child (one transaction)."""
    return in_transaction(database_url, task_id, time_limit_s, _rx_work)


def _run_bounded_kind(
    child: Callable[..., dict[str, Any]], what: str, task_id: int, should_stop: StopFn
) -> dict[str, Any]:
    from fieldrx.services.bounded import run_bounded

    settings = get_settings()
    limit = settings.plan_time_limit_s
    return run_bounded(
        child,
        settings.database_url,
        task_id,
        limit,
        time_limit_s=limit,
        what=what,
        should_stop=should_stop,
    )


def _run_imagery(claimed: store.Claimed, should_stop: StopFn) -> dict[str, Any]:
    """Convert the received upload to a COG and record it; the upload is removed once the
    task has ended either way (a worker killed mid-way leaves it for the retry)."""
    from geoalchemy2.shape import to_shape
    from shapely import wkb

    from fieldrx.imagery import storage
    from fieldrx.imagery.ingest import IngestSpec, ingest
    from fieldrx.services.imagery import imagery_row

    settings = get_settings()
    p = claimed.params
    incoming = incoming_upload(p["incoming"])
    engine = get_engine()
    progress = Progress(raw_dsn(settings.database_url), claimed.id)
    # a fresh key per attempt: a converter orphaned by a killed worker never shares a file
    key = storage.new_key(claimed.organisation_id)
    dst = storage.path_for(key)
    recorded = False
    try:
        with Session(engine) as session:
            field = _scoped(session, Field, p.get("field_id"), claimed.organisation_id, "field")
            spec = IngestSpec(
                kind=p["kind"],
                field_wkb=wkb.dumps(to_shape(field.boundary)),
                utm_epsg=field.utm_epsg,
                red_band=p.get("red_band"),
                nir_band=p.get("nir_band"),
                max_pixels=settings.imagery_max_pixels,
                max_expansion=settings.imagery_max_expansion,
                acquired_on=p.get("acquired_on"),
            )
        if not incoming.is_file():
            raise TaskInputError("the uploaded file is gone (already processed?)")
        dst.parent.mkdir(parents=True, exist_ok=True)
        mb = incoming.stat().st_size / 1024**2
        progress(0.1, f"converting {mb:,.0f} MB to a Cloud-Optimized GeoTIFF")
        res = ingest(incoming, dst, spec, settings.imagery_timeout_s, should_stop=should_stop)
        progress(0.9, "recording the image")
        with Session(engine) as session:
            done = store.guard(session, claimed.id)
            if done is not None:
                return done
            row = imagery_row(
                organisation_id=claimed.organisation_id,
                field_id=int(p["field_id"]),
                kind=p["kind"],
                name=p.get("name", ""),
                filename=p.get("filename", ""),
                storage_key=key,
                res=res,
                created_by=claimed.created_by,
            )
            session.add(row)
            session.flush()
            result = {
                "imagery_id": int(row.id),
                "field_id": int(p["field_id"]),
                "overlap_share": round(res.overlap_share, 4),
                "warnings": res.warnings,
            }
            if not store.complete(session, claimed.id, result, "image stored"):
                session.rollback()
                return {}
            session.commit()
            recorded = True
            return result
    finally:
        progress.close()
        if not recorded:
            dst.unlink(missing_ok=True)
        incoming.unlink(missing_ok=True)


@TASK_KINDS.register
class PlanKind(TaskKind):
    name = "plan"
    result_key, result_route = "plan_id", "/plans/{}"

    def run(self, claimed: store.Claimed, should_stop: StopFn) -> dict[str, Any]:
        return _run_bounded_kind(plan_child, "planning", claimed.id, should_stop)


@TASK_KINDS.register
class PlanBatchKind(TaskKind):
    """Many fields planned at once: a parent row over one ``plan`` task per field."""

    name = "plan_batch"
    batch = True


@TASK_KINDS.register
class PrescriptionKind(TaskKind):
    name = "prescription"
    result_key, result_route = "prescription_id", "/prescriptions/{}"

    def run(self, claimed: store.Claimed, should_stop: StopFn) -> dict[str, Any]:
        return _run_bounded_kind(prescription_child, "the prescription", claimed.id, should_stop)


@TASK_KINDS.register
class ImageryKind(TaskKind):
    name = "imagery"
    result_key, result_route = "imagery_id", "/imagery/{}"

    def run(self, claimed: store.Claimed, should_stop: StopFn) -> dict[str, Any]:
        return _run_imagery(claimed, should_stop)


def worker_name() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def execute(task_id: int, should_abort: StopFn = lambda: False) -> dict[str, Any] | None:
    """Run one task to its end: claim it, run its kind, record failure or cancellation.

    A user error (bad parameters, a field deleted meanwhile, a time limit) fails the task
    with its message and is not retried; an internal error fails it too and is re-raised
    so procrastinate records the job as failed. ``Cancelled`` is re-raised (the queue task
    turns it into an aborted job).
    """
    engine = get_engine()
    claimed = store.claim(engine, task_id, worker_name())
    if claimed is None:
        return None
    kind = TASK_KINDS.get(claimed.kind) if claimed.kind in TASK_KINDS else None
    if kind is None or kind.batch:
        store.finish_failed(engine, task_id, f"unknown task kind {claimed.kind!r}")
        return None

    def should_stop() -> bool:
        return should_abort() or store.is_cancel_requested(engine, task_id)

    try:
        return kind.run(claimed, should_stop)
    except Cancelled:
        store.finish_cancelled(engine, task_id)
        raise
    except Exception as exc:
        if is_user_error(exc):
            store.finish_failed(engine, task_id, str(exc))
            return {"error": str(exc)}
        log.exception("task %s (%s) failed", task_id, claimed.kind)
        store.finish_failed(
            engine, task_id, f"internal error ({type(exc).__name__}); nothing was stored"
        )
        raise
