"""As-applied reports of a job: per-cell accuracy, GeoJSON, vector tiles, CSV/Shapefile, summary.

The figures come from ``fieldrx.fleet.reports`` (seed 001 eq. 17-18). The
vector tiles carry the report's own per-cell figures (``applied_rate`` = M2 over
the cell's area, ``accuracy`` = eq. 18, ``n_records``), from
``fleet.reports.cached_report``: computed once per change of the job's
telemetry, so the map colours a cell by the accuracy the side panel shows.
"""

from __future__ import annotations

import datetime as dt
import json
from dataclasses import asdict, fields
from typing import Any

from fastapi import APIRouter, Query, Request
from fastapi.responses import FileResponse, Response
from fieldrx_edge.jobkinds.registry import kind_of
from sqlalchemy import select, text

from fieldrx.api.common import ApiError, get_scoped, point_page
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.files import MVT, file_response
from fieldrx.api.schemas.fleet import PointPage
from fieldrx.api.schemas.formats import JobExportFormat
from fieldrx.api.schemas.reports import (
    AsAppliedCells,
    AsAppliedReport,
    JobSummaryOut,
    KindReport,
    RawLogState,
)
from fieldrx.api.schemas.tasks import QUEUED
from fieldrx.api.tasks import accepted, queue_task
from fieldrx.auth.deps import SessionDep, UserDep, WriterDep
from fieldrx.db.models import Field, Job, JobEvent, Prescription
from fieldrx.fleet.partitions import job_window
from fieldrx.fleet.reports import (
    CellReport,
    JobReport,
    cache_get,
    cached_report,
    job_plan,
    key_records,
    report_digest,
    report_key,
)
from fieldrx.services.prescriptions.versions import report_unit
from fieldrx.settings import get_settings
from fieldrx.store import load_cells
from fieldrx.store import tiles as cell_tiles
from fieldrx.tasks.exports import open_report_task, stored_report

router = APIRouter(tags=["reports"], responses=ERRORS)


def _report(session: SessionDep, job_id: int, principal: Any) -> tuple[Job, JobReport]:
    job = get_scoped(session, Job, job_id, principal)
    _prescription_job(job)
    return job, _cached(session, job)


def _cached(session: SessionDep, job: Job) -> JobReport:
    """The job's report: this process's cache, a report task's stored snapshot, or built."""
    org = job.organisation_id
    return cached_report(session, job, lambda d: stored_report(session, org, job.id, d))


BACKGROUND = Query(
    default=None,
    description="true: run as a task (202 with it) unless the answer is ready; false: "
    "inline whatever the size; unset: a task when the job has more than "
    "FIELDRX_REPORT_BACKGROUND_RECORDS records",
)


def _ready_or_cheap(session: SessionDep, job: Job, background: bool | None) -> bool:
    """Answer inline? Yes when asked to, when the report is cached here or stored by a
    report task, or (unless ``background=true``) when the job is small."""
    if background is False:
        return True
    key = report_key(session, job)
    if cache_get(session, job, key) is not None:
        return True
    if stored_report(session, job.organisation_id, job.id, report_digest(key)) is not None:
        return True
    return background is None and key_records(key) <= get_settings().report_background_records


def _queue_report(session: SessionDep, principal: Any, job: Job) -> Any:
    """202 with the job's report task: the open one for the same data, or a new one."""
    from fieldrx.db.models import Task

    digest = report_digest(report_key(session, job))
    tid = open_report_task(session, job.organisation_id, job.id, digest)
    task = session.get(Task, tid) if tid is not None else None
    if task is not None:
        return accepted(session, task)
    return queue_task(session, principal, "report", {"job_id": job.id, "key": digest})


def _prescription_job(job: Job) -> None:
    """The per-cell as-applied views are seed 001's (prescribed vs applied rate); a sensor
    job has its own report."""
    if kind_of(job.kind).rates_from == "sensors":
        raise ApiError(
            409,
            f"job {job.id} is a {job.kind} job: its figures are in GET /jobs/{job.id}/report",
            where="job_id",
        )


@router.get(
    "/jobs/{job_id:int}/report", response_model=AsAppliedReport | KindReport, responses=QUEUED
)
def job_report(
    job_id: int,
    principal: UserDep,
    session: SessionDep,
    cells: bool = Query(default=True, description="include the per-cell rows"),
    background: bool | None = BACKGROUND,
) -> Any:
    """Per-cell target vs applied rate and accuracy theta, coverage, totals, time worked.
    Sensor kinds get their own report (fieldrx.fleet.seed_reports: NDVI / depth maps and the
    papers' Table 3).

    A large job's report is computed by a task worker (``background``): 202 with the
    ``report`` task (asking again while it runs joins it); once it succeeded, this answers
    200 from its stored snapshot, as do the job's tiles and exports."""
    job = get_scoped(session, Job, job_id, principal)
    if kind_of(job.kind).rates_from == "sensors":
        from fieldrx.fleet.seed_reports import kind_report

        return kind_report(session, job, cells=cells)
    if not _ready_or_cheap(session, job, background):
        return _queue_report(session, principal, job)
    _, rep = _report(session, job_id, principal)
    out = rep.summary()
    rx = session.get(Prescription, job.prescription_id) if job.prescription_id else None
    if rx is not None:
        out["unit"] = report_unit(rx, rep.planned_total_kg, rep.applied_total_kg)
    if cells:
        out["cells"] = [asdict(c) for c in rep.cells]
    return out


@router.post("/jobs/{job_id:int}/raw-log/request", status_code=202, response_model=RawLogState)
def request_raw_log(job_id: int, principal: WriterDep, session: SessionDep) -> dict[str, Any]:
    """Ask the job's tractor for its full 10 Hz log (a thin-profile job keeps it on board);
    it arrives with the agent's next ``upload-log`` and is then served by GET below. It
    makes the tractor upload, so it needs a role that may write (a viewer only reads)."""
    from fieldrx.fleet import rawlogs

    job = get_scoped(session, Job, job_id, principal)
    if not rawlogs.log_path(job.organisation_id, job.id).exists():
        rawlogs.request(job.organisation_id, job.id)
    return {"job_id": job.id, "state": _raw_log_state(job)}


def _raw_log_state(job: Job) -> str:
    from fieldrx.fleet import rawlogs

    if rawlogs.log_path(job.organisation_id, job.id).exists():
        return "uploaded"
    return "requested" if rawlogs.requested(job.organisation_id, job.id) else "not requested"


@router.get(
    "/jobs/{job_id:int}/raw-log",
    response_class=Response,
    responses=file_response("the job's 10 Hz log: gzip of JSON lines", "application/gzip"),
)
def get_raw_log(job_id: int, principal: UserDep, session: SessionDep) -> Response:
    """The job's full 10 Hz log as the tractor uploaded it (gzip of JSON lines)."""
    from fieldrx.fleet import rawlogs

    job = get_scoped(session, Job, job_id, principal)
    path = rawlogs.log_path(job.organisation_id, job.id)
    if not path.exists():
        raise ApiError(404, f"job {job_id}: raw log {_raw_log_state(job)}, not uploaded")
    return FileResponse(path, media_type="application/gzip", filename=f"job-{job.id}-raw.jsonl.gz")


@router.get("/jobs/{job_id:int}/summary", response_model=JobSummaryOut)
def job_summary(job_id: int, principal: UserDep, session: SessionDep) -> dict[str, Any]:
    """Compact job record for farm software: what, where, when, how much, how well."""
    job, rep = _report(session, job_id, principal)
    rx = session.get(Prescription, job.prescription_id)
    plan = job_plan(session, job)
    fld = session.get(Field, plan.field_id)
    events = session.execute(
        select(JobEvent.state, JobEvent.at)
        .where(JobEvent.machine_id == job.machine_id, JobEvent.job_id == job.id)
        .order_by(JobEvent.id)
    ).all()
    started = next((e.at for e in events if e.state == "running"), None)
    ended = next((e.at for e in reversed(events) if e.state in ("completed", "aborted")), None)
    return {
        "job_id": job.id,
        "name": job.name,
        "state": job.state,
        "field": {"id": fld.id, "name": fld.name} if fld else None,
        "machine_id": job.machine_id,
        "prescription": {
            "id": job.prescription_id,
            "version": job.prescription_version,
            "product": rx.product if rx else "",
        },
        "started_at": started,
        "ended_at": ended,
        "first_record_at": rep.summary()["first_t"],
        "last_record_at": rep.summary()["last_t"],
        "time_worked_s": rep.time_worked_s,
        "area_applied_ha": rep.applied_area_m2 / 1e4,
        "field_area_ha": rep.field_area_m2 / 1e4,
        "planned_area_ha": rep.planned_area_m2 / 1e4,
        "area_basis": rep.area_basis,
        "coverage_pct": rep.coverage_pct,
        "planned_total_kg": rep.planned_total_kg,
        "never_applied_kg": rep.never_applied_kg,
        "applied_total_kg": rep.applied_total_kg,
        "applied_outside_cells_kg": rep.applied_outside_cells_kg,
        "mean_accuracy_pct": rep.mean_accuracy_pct,
        "min_accuracy_pct": rep.min_accuracy_pct,
        "cells_planned": rep.cells_planned,
        "cells_applied": rep.cells_applied,
        "unit": "kg",
    }


@router.get("/jobs/{job_id:int}/as-applied", response_model=PointPage)
def as_applied_points(
    job_id: int,
    principal: UserDep,
    session: SessionDep,
    limit: int = Query(default=5000, ge=1, le=50000),
    offset: int = Query(default=0, ge=0),
) -> Response:
    """As-applied points (one per record with a position), in time order, paged."""
    job = get_scoped(session, Job, job_id, principal)
    params = {
        "m": job.machine_id,
        "j": job.id,
        "lim": limit,
        "off": offset,
        **job_window(session, job.machine_id, job.id),
    }
    where = "machine_id = :m AND job_id = :j AND t BETWEEN :t0 AND :t1 AND geom IS NOT NULL"
    total = session.execute(text(f"SELECT count(*) FROM telemetry WHERE {where}"), params).scalar()
    rows = session.execute(
        text(
            "SELECT seq, extract(epoch FROM t)::float8 AS t, ST_X(geom) AS lon, ST_Y(geom) AS lat,"
            " cell_seq, target_rate_kg_ha, applied_rate_kg_ha, speed_filtered_m_s,"
            f" implement_down FROM telemetry WHERE {where} ORDER BY t, seq LIMIT :lim OFFSET :off"
        ),
        params,
    )
    return point_page(rows, total or 0, limit, offset)


@router.get("/jobs/{job_id:int}/as-applied/cells", response_model=AsAppliedCells)
def as_applied_cells(job_id: int, principal: UserDep, session: SessionDep) -> dict[str, Any]:
    """Per-cell GeoJSON: planned vs applied rate, masses and accuracy."""
    job, rep = _report(session, job_id, principal)
    plan = job_plan(session, job)
    fld = session.get(Field, plan.field_id)
    cells = load_cells(session, rep.plan_id, fld.utm_epsg if fld is not None else 0)
    by_seq = {c.seq: c for c in rep.cells}
    rows = [by_seq.get(int(q)) for q in cells.seq]
    names = [f.name for f in fields(CellReport)]
    columns = {k: [None if r is None else getattr(r, k) for r in rows] for k in names}
    feats = [json.loads(f) for f in cells.geojson_features(columns)]
    return {"type": "FeatureCollection", "features": feats, "summary": rep.summary()}


@router.get(
    "/jobs/{job_id:int}/export",
    response_class=Response,
    responses={
        **file_response(
            "per-cell CSV, zipped Shapefile or TASKDATA.zip (Content-Disposition names it)",
            "text/csv",
            "application/zip",
        ),
        **QUEUED,
    },
)
def export_report(
    job_id: int,
    principal: UserDep,
    session: SessionDep,
    format: JobExportFormat = "csv",  # noqa: A002
    background: bool | None = BACKGROUND,
) -> Response:
    """Per-cell as-applied table as CSV; zipped Shapefile (cell polygons + record points);
    ISO 11783-10 TASKDATA.zip with a TimeLog (``formats.asapplied``).

    A large job's export runs as an ``export`` task (``background``): 202 with the task,
    whose ``result_url`` downloads the file once it succeeded (``GET /tasks/{id}/download``).
    """
    job = get_scoped(session, Job, job_id, principal)
    _prescription_job(job)
    if background or (
        background is None
        and key_records(report_key(session, job)) > get_settings().report_background_records
    ):
        params = {"source": "job", "job_id": job.id, "format": format}
        return queue_task(session, principal, "export", params)
    rep = _cached(session, job)
    from fieldrx.formats import FormatError
    from fieldrx.services.asapplied import export_job

    try:
        data, media, filename = export_job(session, job, rep, format)
    except FormatError as exc:
        raise ApiError(422, f"job {job.id}: {exc}", where="format") from exc
    return Response(
        data,
        media_type=media,
        headers={"Content-Disposition": f'attachment; filename="{filename}"'},
    )


@router.get(
    "/tiles/jobs/{job_id:int}/{z:int}/{x:int}/{y:int}.mvt",
    response_class=Response,
    responses=file_response("a Mapbox vector tile, layer 'cells'", MVT),
)
def job_tile(
    job_id: int, z: int, x: int, y: int, request: Request, principal: UserDep, session: SessionDep
) -> Response:
    """Vector tile, layer "cells": seq, swath, target_rate, applied_rate, accuracy, n_records."""
    if not 0 <= z <= 24 or not (0 <= x < (1 << z) and 0 <= y < (1 << z)):
        raise ApiError(422, f"tile {z}/{x}/{y} does not exist", where="z/x/y")
    job = get_scoped(session, Job, job_id, principal)
    _prescription_job(job)
    plan = job_plan(session, job)
    cells = _cached(session, job).cells  # the report's figures, not a second formula
    figures = cell_tiles.JobCellFigures(
        [c.seq for c in cells],
        [c.target_rate_kg_ha for c in cells],
        [c.applied_rate_kg_ha for c in cells],
        [c.accuracy_pct for c in cells],
        [c.n_records for c in cells],
    )
    data = cell_tiles.job_tile(session, plan.id, z, x, y, figures)
    return Response(
        bytes(data or b""),
        media_type=MVT,
        headers={"Cache-Control": "no-cache", "Last-Modified": _http_date(job.updated_at)},
    )


def _http_date(t: dt.datetime) -> str:
    return t.astimezone(dt.UTC).strftime("%a, %d %b %Y %H:%M:%S GMT")
