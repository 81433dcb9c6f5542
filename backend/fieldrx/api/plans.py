"""Coverage plans of a field: create (plan + grid + store), summary, cells, route, delete."""

from __future__ import annotations

import json
from typing import Any

from fastapi import APIRouter, Query
from sqlalchemy import func, select
from sqlalchemy.exc import OperationalError

from fieldrx.api.common import ApiError, get_scoped
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.plans import PlanCellPage, PlanIn, PlanList, PlanOut, RouteOut
from fieldrx.api.schemas.prescriptions import PrescriptionList
from fieldrx.api.schemas.tasks import QUEUED
from fieldrx.auth.deps import SessionDep, UserDep, WriterDep
from fieldrx.db.models import Field as FieldRow
from fieldrx.db.models import Plan, Prescription
from fieldrx.geo import PlanningError
from fieldrx.services.evidence import refuse_if_evidence
from fieldrx.services.plans import (
    PlanParams,
    cells_page,
    create_plan_bounded,
    delete_plan,
    plan_summary,
)

router = APIRouter(tags=["plans"], responses=ERRORS)

MAX_PAGE = 50_000


BACKGROUND = Query(
    default=False,
    description="queue the work for a `fieldrx worker` and answer 202 with the task "
    "(poll /api/v1/tasks/{id}) instead of waiting for it",
)


@router.post(
    "/fields/{field_id:int}/plans", status_code=201, response_model=PlanOut, responses=QUEUED
)
def create(
    field_id: int,
    body: PlanIn,
    principal: WriterDep,
    session: SessionDep,
    background: bool = BACKGROUND,
) -> Any:
    """Plan the coverage path, cut the grid and store both (one transaction).

    Bad parameters (w <= 0, w wider than the field, L < 0.5 m, > 5 million
    cells, degenerate field) answer 422 with the planner's reason; the cell count
    is estimated before any work. Planning runs in a worker process with a time
    limit (FIELDRX_PLAN_TIME_LIMIT_S, 422 when exceeded; 503 when all workers are busy).
    With ``background=true`` it is queued instead: 202 with the task.
    """
    field = get_scoped(session, FieldRow, field_id, principal)
    params = PlanParams(**body.model_dump())
    if background:
        from fieldrx.api.tasks import queue_plan

        return queue_plan(session, principal, field, params)
    try:
        plan = create_plan_bounded(session, field, params, field.organisation_id)
    except PlanningError as exc:
        raise ApiError(422, str(exc)) from exc
    return plan_summary(plan)


@router.get("/fields/{field_id:int}/plans", response_model=PlanList)
def list_plans(field_id: int, principal: UserDep, session: SessionDep) -> dict[str, Any]:
    field = get_scoped(session, FieldRow, field_id, principal)
    rows = session.scalars(
        select(Plan).where(Plan.field_id == field.id).order_by(Plan.id.desc())
    ).all()
    return {"items": [plan_summary(p) for p in rows], "total": len(rows)}


@router.get("/plans/{plan_id:int}", response_model=PlanOut)
def get_plan(plan_id: int, principal: UserDep, session: SessionDep) -> dict[str, Any]:
    return plan_summary(get_scoped(session, Plan, plan_id, principal))


@router.get("/plans/{plan_id:int}/cells", response_model=PlanCellPage)
def get_cells(
    plan_id: int,
    principal: UserDep,
    session: SessionDep,
    limit: int = Query(default=1000, ge=1, le=MAX_PAGE),
    offset: int = Query(default=0, ge=0),
) -> dict[str, Any]:
    """Cells in path order as a GeoJSON FeatureCollection (paged by seq)."""
    plan = get_scoped(session, Plan, plan_id, principal)
    return {
        "type": "FeatureCollection",
        "features": cells_page(session, plan.id, limit, offset),
        "total": plan.n_cells,
        "limit": limit,
        "offset": offset,
    }


@router.get("/plans/{plan_id:int}/route", response_model=RouteOut)
def get_route(plan_id: int, principal: UserDep, session: SessionDep) -> dict[str, Any]:
    """The whole route (swaths and connections in driving order) as a LineString Feature."""
    plan = get_scoped(session, Plan, plan_id, principal)
    gj = session.scalar(select(func.ST_AsGeoJSON(Plan.route, 9)).where(Plan.id == plan.id))
    if gj is None:
        raise ApiError(404, f"plan {plan_id} has no route")
    m = plan.metrics or {}
    keys = ("n_swaths", "n_turns", "heading_deg", "working_length_m", "nonworking_length_m")
    return {
        "type": "Feature",
        "id": plan.id,
        "geometry": json.loads(gj),
        "properties": {"plan_id": plan.id, **{k: m.get(k) for k in keys}},
    }


@router.get("/plans/{plan_id:int}/prescriptions", response_model=PrescriptionList)
def list_plan_prescriptions(plan_id: int, principal: UserDep, session: SessionDep) -> dict:
    from fieldrx.services.prescriptions.versions import prescription_summary

    plan = get_scoped(session, Plan, plan_id, principal)
    rows = session.scalars(
        select(Prescription).where(Prescription.plan_id == plan.id).order_by(Prescription.id)
    ).all()
    return {"items": [prescription_summary(session, r) for r in rows], "total": len(rows)}


@router.delete("/plans/{plan_id:int}", status_code=204)
def remove_plan(plan_id: int, principal: WriterDep, session: SessionDep) -> None:
    """Delete the plan, its cells and the prescriptions made on it."""
    plan = get_scoped(session, Plan, plan_id, principal)
    refuse_if_evidence(session, "plan", plan.id)
    try:
        delete_plan(session, plan)
    except OperationalError as exc:
        session.rollback()
        raise ApiError(409, f"plan {plan_id} is in use (its cells are being read); retry") from exc
    session.commit()
