"""Plans in PostGIS: run the pure planner (fieldrx.geo) and store its grid fast.

The plan row and its cells are written in one transaction; the cells go
through the cell store (``fieldrx.store``: one partition per plan, binary COPY)
so a 1,000 ha field with about 870k cells stores in seconds, and come back
from it as the one cell type (``fieldrx.geo.cells.Cells``).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
from geoalchemy2.shape import to_shape
from sqlalchemy import text
from sqlalchemy.orm import Session

from fieldrx.db.geometry import shape_to_db
from fieldrx.db.models import Field, Plan
from fieldrx.geo import PlanningError
from fieldrx.geo.coverage import plan_coverage
from fieldrx.geo.crs import to_utm, to_wgs84
from fieldrx.geo.grid import build_grid, check_grid_cost
from fieldrx.geo.planning.kinematics import DEFAULT_HEADLAND_PASSES
from fieldrx.services.evidence import delete_jobs
from fieldrx.store import load_cells, write_plan_cells


@dataclass
class PlanParams:
    swath_width_m: float = 2.3
    cell_length_m: float = 5.0
    heading: str = "longest_edge"
    angle_deg: float | None = None
    headland_passes: int = DEFAULT_HEADLAND_PASSES
    start_corner: str = "sw"
    headland_order: str = "first"
    min_cell_fraction: float = 0.1
    turn_radius_m: float = 6.0
    reverse: bool = False
    pattern: str = "boustrophedon"


def field_utm(field: Field) -> Any:
    return to_utm(to_shape(field.boundary), field.utm_epsg)


STORE_LOCK_NS = 7004  # advisory lock namespace: plans are stored one at a time (create_plan)


def delete_plan(session: Session, plan: Plan) -> None:
    """Delete the plan; a trigger (migration 0002) drops its partition, no row-by-row delete.

    Dropping a partition needs a short exclusive lock on plan_cells; the lock wait is
    bounded so a busy table makes this fail (sqlalchemy OperationalError) instead of
    queueing every tile request behind it.
    """
    session.execute(text("SET LOCAL lock_timeout = '5s'"))
    delete_jobs(session, "plan", plan.id)
    session.delete(plan)
    session.flush()


def check_plan_cost(area_m2: float, params: PlanParams) -> None:
    """Refuse, before any planning, a plan whose grid would exceed ``MAX_CELLS`` or whose
    cells are shorter than the minimum (``geo.grid.check_grid_cost``: the one estimate)."""
    check_grid_cost(area_m2, params.swath_width_m, params.cell_length_m)


def plan_in_worker(
    database_url: str, field_id: int, params: PlanParams, organisation_id: int, time_limit_s: float
) -> int:
    """``create_plan`` and commit on a connection of its own (run by ``services.bounded``
    in a child process); returns the new plan's id."""
    from sqlalchemy.orm import Session as OrmSession

    from fieldrx.db.session import limit_session, make_engine
    from fieldrx.services.bounded import ensure_caller_alive

    engine = make_engine(database_url)
    try:
        with OrmSession(engine) as session:
            limit_session(session, time_limit_s)
            field = session.get(Field, field_id)
            if field is None:
                raise PlanningError(f"field {field_id} was deleted while planning")
            plan = create_plan(session, field, params, organisation_id)
            ensure_caller_alive("planning")
            session.commit()
            return int(plan.id)
    finally:
        engine.dispose()


def create_plan_bounded(
    session: Session, field: Field, params: PlanParams, organisation_id: int
) -> Plan:
    """``create_plan`` with its cost checked first and run off the server process with the
    ``FIELDRX_PLAN_TIME_LIMIT_S`` limit (services.bounded); commits in the worker.

    The session's transaction is ended first: no transaction of the server stays open
    while the worker plans."""
    field_id, area_m2 = field.id, field.area_m2
    session.rollback()
    from fieldrx.services.bounded import run_bounded
    from fieldrx.settings import get_settings

    check_plan_cost(area_m2, params)
    limit = get_settings().plan_time_limit_s
    url = session.get_bind().engine.url.render_as_string(hide_password=False)
    plan_id = run_bounded(
        plan_in_worker,
        url,
        field_id,
        params,
        organisation_id,
        limit,
        time_limit_s=limit,
        what="planning",
    )
    plan = session.get(Plan, plan_id)
    assert plan is not None
    return plan


ProgressFn = Callable[[float, str], None]


def _no_progress(share: float, message: str) -> None:
    return None


def create_plan(
    session: Session,
    field: Field,
    params: PlanParams,
    organisation_id: int,
    progress: ProgressFn = _no_progress,
) -> Plan:
    """Plan + grid + store (flushes, does not commit). Raises ``PlanningError``.

    ``progress(share, message)`` is called between the stages (a background task shows it;
    it may raise to stop the work, which then stores nothing)."""
    t0 = time.perf_counter()
    check_plan_cost(field.area_m2, params)
    progress(0.05, "planning the coverage path")
    boundary = field_utm(field)
    cov = plan_coverage(
        boundary,
        swath_width_m=params.swath_width_m,
        heading=params.heading,  # type: ignore[arg-type]
        angle_deg=params.angle_deg,
        headland_passes=params.headland_passes,
        start_corner=params.start_corner,  # type: ignore[arg-type]
        headland_order=params.headland_order,  # type: ignore[arg-type]
        turn_radius_m=params.turn_radius_m,
        reverse=params.reverse,
        pattern=params.pattern,
    )
    t_plan = time.perf_counter()
    progress(0.4, "cutting the path into cells")
    grid = build_grid(
        cov,
        boundary,
        cell_length_m=params.cell_length_m,
        min_cell_fraction=params.min_cell_fraction,
        epsg=field.utm_epsg,
    )
    t_grid = time.perf_counter()
    progress(0.6, f"storing {len(grid):,} cells")
    metrics: dict[str, Any] = dict(cov.metrics())
    metrics["n_cells"] = len(grid)
    metrics["cells_uncovered_m2"] = round(grid.uncovered_m2, 3)
    metrics["epsg"] = field.utm_epsg
    route = to_wgs84(cov.route(), field.utm_epsg)
    plan = Plan(
        organisation_id=organisation_id,
        field_id=field.id,
        params={k: v for k, v in params.__dict__.items()},
        metrics=metrics,
        heading_deg=float(cov.heading_deg),
        n_cells=len(grid),
        route=shape_to_db(route),
    )
    # Stores take turns (lock held to commit): ATTACH PARTITION needs SHARE ROW EXCLUSIVE on
    # plans, which every other transaction that inserted a plan row holds against it while
    # it waits for plan_cells in turn; two concurrent stores deadlocked (PostgreSQL aborted
    # one: found by two task workers planning at once). Planning and the grid stay parallel.
    session.execute(text("SELECT pg_advisory_xact_lock(:ns, 0)"), {"ns": STORE_LOCK_NS})
    # this transaction attaches a bulk-built partition itself (migration 0002 trigger)
    session.execute(text("SELECT set_config('fieldrx.bulk_plan_cells', 'on', true)"))
    session.add(plan)
    session.flush()
    session.execute(text("SELECT set_config('fieldrx.bulk_plan_cells', 'off', true)"))
    store = write_plan_cells(session, plan.id, grid)
    t_store = time.perf_counter()
    # cells a notch or hole splits in parts (stored whole, as MultiPolygons)
    metrics["multipart_cells"] = int((shapely.get_type_id(grid.polygons_utm) == 6).sum())
    metrics["timings_s"] = {
        "plan": round(t_plan - t0, 4),
        "grid": round(t_grid - t_plan, 4),
        "store": round(t_store - t_grid, 4),
        "store_copy": round(store["copy_s"], 4),
        "store_index": round(store["index_attach_s"], 4),
        "total": round(t_store - t0, 4),
    }
    plan.metrics = metrics
    session.flush()
    return plan


def plan_summary(plan: Plan) -> dict[str, Any]:
    p = plan.params or {}
    return {
        "id": plan.id,
        "field_id": plan.field_id,
        "params": p,
        "heading_deg": plan.heading_deg,
        "n_cells": plan.n_cells,
        "metrics": plan.metrics,
        "created_at": plan.created_at.isoformat() if plan.created_at else None,
    }


def cells_page(session: Session, plan_id: int, limit: int, offset: int) -> list[dict[str, Any]]:
    """GeoJSON features of cells offset .. offset+limit-1 in path order (seq is 0..n-1)."""
    plan = session.get(Plan, plan_id)
    field = session.get(Field, plan.field_id) if plan is not None else None
    if plan is None or field is None:
        raise LookupError(f"plan {plan_id} or its field is gone")
    cells = load_cells(session, plan_id, field.utm_epsg, offset, offset + limit)
    feats = cells.geojson_features(
        {
            "seq": cells.seq,
            "swath": cells.swath,
            "index_in_swath": cells.index_in_swath,
            "area_m2": np.round(cells.area_m2, 3),
        }
    )
    return [json.loads(f) for f in feats]
