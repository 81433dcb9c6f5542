"""Background tasks of the organisation: status and progress, cancel, and batch planning.

A request that runs in the background (``?background=true`` on planning and
prescriptions, large imagery uploads, and every batch) answers ``202 Accepted`` with the
task (``Location: /api/v1/tasks/{id}``); poll ``GET /tasks/{id}`` for status, progress
(0..1), message, ``result_url`` once it succeeded, ``error`` if it failed. Tasks are run
by ``fieldrx worker`` processes (``fieldrx.tasks``). An export task's file is downloaded
from ``GET /tasks/{id}/download`` until its retention ends (``tasks.files``).
"""

from __future__ import annotations

from typing import Any, Literal

from fastapi import APIRouter, Query
from fastapi.responses import JSONResponse, Response, StreamingResponse
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from fieldrx.api.common import ApiError, get_scoped
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.files import file_response
from fieldrx.api.schemas.tasks import MAX_BATCH, QUEUED, PlanBatchIn, TaskList, TaskOut
from fieldrx.auth.deps import Principal, SessionDep, UserDep, WriterDep
from fieldrx.db.models import Field as FieldRow
from fieldrx.db.models import Task
from fieldrx.db.session import get_engine
from fieldrx.geo import PlanningError
from fieldrx.services.plans import PlanParams, check_plan_cost

# work: importing it registers every task kind, which the tasks' result links come from
from fieldrx.tasks import files, store, work  # noqa: F401
from fieldrx.tasks.kinds import stores_file

router = APIRouter(tags=["tasks"], responses=ERRORS)


def accepted(session: Session, row: Task) -> JSONResponse:
    """202 with the task's view and its URL in ``Location``."""
    body = store.task_view(session, row, with_children=False)
    return JSONResponse(status_code=202, content=body, headers={"Location": body["url"]})


def _check_cost(field: FieldRow, params: PlanParams) -> None:
    try:
        check_plan_cost(field.area_m2, params)
    except PlanningError as exc:
        raise ApiError(422, f"field {field.id}: {exc}") from exc


def queue_plan(
    session: Session, principal: Principal, field: FieldRow, params: PlanParams
) -> JSONResponse:
    """Queue one plan (the cost is checked first, so impossible parameters are a 422 now)."""
    _check_cost(field, params)
    (row,) = store.create_tasks(
        session,
        organisation_id=principal.organisation_id,
        created_by=principal.user_id,
        kind="plan",
        params_list=[{"field_id": field.id, "plan": dict(params.__dict__)}],
    )
    session.commit()
    return accepted(session, row)


def queue_task(
    session: Session, principal: Principal, kind: str, params: dict[str, Any]
) -> JSONResponse:
    """Queue one task of ``kind`` with ``params`` and answer 202."""
    (row,) = store.create_tasks(
        session,
        organisation_id=principal.organisation_id,
        created_by=principal.user_id,
        kind=kind,
        params_list=[params],
    )
    session.commit()
    return accepted(session, row)


@router.post("/plans/batch", status_code=202, response_model=TaskOut, responses=QUEUED)
def plan_batch(body: PlanBatchIn, principal: WriterDep, session: SessionDep) -> JSONResponse:
    """Queue one plan task per field under a batch task (202 with the batch; its progress
    is the mean of its children's, ``items`` lists them with their ``result_url``).

    Every field must be the organisation's (422 naming those that are not) and every plan's
    cell count is checked first (422 naming the field); nothing is queued then."""
    org = principal.organisation_id
    if body.farm_id is not None:
        stmt = select(FieldRow).where(
            FieldRow.organisation_id == org, FieldRow.farm_id == body.farm_id
        )
        fields = list(session.scalars(stmt.order_by(FieldRow.id)))
        if not fields:
            raise ApiError(422, f"farm {body.farm_id} has no fields", where="farm_id")
    else:
        ids = list(dict.fromkeys(body.field_ids or []))
        found = {
            f.id: f
            for f in session.scalars(
                select(FieldRow).where(FieldRow.organisation_id == org, FieldRow.id.in_(ids))
            )
        }
        missing = [i for i in ids if i not in found]
        if missing:
            raise ApiError(422, f"fields not found: {missing[:20]}", where="field_ids")
        fields = [found[i] for i in ids]
    if len(fields) > MAX_BATCH:
        raise ApiError(422, f"{len(fields)} fields, more than {MAX_BATCH} in one batch")
    params = PlanParams(**body.params.model_dump())
    for f in fields:
        _check_cost(f, params)
    plan = dict(params.__dict__)
    parent, _ = store.create_batch(
        session,
        organisation_id=org,
        created_by=principal.user_id,
        kind="plan",
        params_list=[{"field_id": f.id, "plan": plan} for f in fields],
        batch_params={"field_ids": [f.id for f in fields], "farm_id": body.farm_id, "plan": plan},
    )
    session.commit()
    return accepted(session, parent)


@router.get("/tasks", response_model=TaskList)
def list_tasks(
    principal: UserDep,
    session: SessionDep,
    status: Literal["queued", "running", "succeeded", "failed", "cancelled"] | None = None,
    kind: str | None = None,
    parent_id: int | None = Query(default=None, description="a batch's children"),
    limit: int = Query(default=50, ge=1, le=500),
    offset: int = Query(default=0, ge=0),
) -> dict[str, Any]:
    """The organisation's tasks, newest first (top-level ones unless ``parent_id``).
    ``status`` filters the stored status (a batch's own is derived: see its view)."""
    stmt = select(Task).where(Task.organisation_id == principal.organisation_id)
    stmt = stmt.where(Task.parent_id == parent_id if parent_id else Task.parent_id.is_(None))
    if status is not None:
        stmt = stmt.where(Task.status == status)
    if kind is not None:
        stmt = stmt.where(Task.kind == kind)
    total = session.scalar(select(func.count()).select_from(stmt.subquery())) or 0
    rows = session.scalars(stmt.order_by(Task.id.desc()).limit(limit).offset(offset)).all()
    return {
        "items": [store.task_view(session, r, with_children=False) for r in rows],
        "total": int(total),
        "limit": limit,
        "offset": offset,
    }


@router.get("/tasks/{task_id:int}", response_model=TaskOut)
def get_task(task_id: int, principal: UserDep, session: SessionDep) -> dict[str, Any]:
    """Status, progress 0..1, message, result and ``result_url``, error; a batch adds
    ``counts`` and its children as ``items``."""
    return store.task_view(session, get_scoped(session, Task, task_id, principal))


@router.post("/tasks/{task_id:int}/cancel", status_code=202, response_model=TaskOut)
def cancel_task(task_id: int, principal: WriterDep, session: SessionDep) -> dict[str, Any]:
    """Cancel a task (a batch: all its unfinished children). Queued ones end at once; a
    running one stops within about a second and stores nothing. 409 when it already ended."""
    row = get_scoped(session, Task, task_id, principal)
    view = store.task_view(session, row, with_children=False)
    if view["status"] in store.FINAL:
        raise ApiError(409, f"task {task_id} already ended ({view['status']})")
    counts = store.request_cancel(session, row)
    session.commit()
    return {**store.task_view(session, row, with_children=False), **counts}


@router.get(
    "/tasks/{task_id:int}/download",
    response_class=Response,
    responses={
        **file_response(
            "the file the task produced (Content-Disposition names it)",
            "text/csv",
            "application/zip",
            "application/geo+json",
            "application/gzip",
        ),
        410: {"description": "the file was deleted after its retention: run the task again"},
    },
)
def download(task_id: int, principal: UserDep, session: SessionDep) -> Response:
    """The file a succeeded export (or report) task produced, streamed with its media type.
    409 while the task has not succeeded; 410 once the file passed its retention
    (``FIELDRX_TASK_RESULT_RETENTION_S``)."""
    row = get_scoped(session, Task, task_id, principal)
    if row.status != "succeeded":
        raise ApiError(409, f"task {task_id} is {row.status}: there is no file to download yet")
    meta = files.info(session, task_id)
    if meta is None:
        if stores_file(row.kind):
            raise ApiError(
                410,
                f"task {task_id}'s file was deleted after its retention; run the export again",
            )
        raise ApiError(404, f"task {task_id} ({row.kind}) produces no file; see its result_url")
    session.close()  # the stream reads on its own short connections
    return StreamingResponse(
        files.iter_chunks(get_engine(), task_id, meta.size),
        media_type=meta.media_type,
        headers={
            "Content-Disposition": f'attachment; filename="{meta.filename}"',
            "Content-Length": str(meta.size),
        },
    )
