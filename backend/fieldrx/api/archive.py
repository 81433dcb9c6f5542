"""Job archives: a job's as-applied evidence, kept after what it was made from is deleted.

``POST /jobs/{id}/archive`` copies the job summary and its per-cell as-applied
GeoJSON (the same bodies as ``/jobs/{id}/summary`` and
``/jobs/{id}/as-applied/cells``) into ``job_archives``. Only then may the
job's machine, field, plan or prescription be deleted (services.evidence).
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Query
from sqlalchemy import func, select

from fieldrx.api.common import ApiError
from fieldrx.api.reports import as_applied_cells, job_summary
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.reports import ArchiveList, ArchiveOut
from fieldrx.auth.deps import SessionDep, UserDep, WriterDep
from fieldrx.db.models import Job, JobArchive

router = APIRouter(tags=["archive"], responses=ERRORS)


def _out(a: JobArchive, full: bool) -> dict[str, Any]:
    out: dict[str, Any] = {
        "job_id": a.job_id,
        "name": a.name,
        "archived_at": a.archived_at.isoformat() if a.archived_at else None,
        "archived_by": a.archived_by,
        "summary": a.summary,
    }
    if full:
        out["cells"] = a.cells
    return out


@router.post("/jobs/{job_id:int}/archive", status_code=201, response_model=ArchiveOut)
def archive_job(job_id: int, principal: WriterDep, session: SessionDep) -> dict[str, Any]:
    """Archive (again: replaces the previous copy) the job's as-applied evidence."""
    summary = job_summary(job_id, principal, session)  # 404 for another organisation's job
    cells = as_applied_cells(job_id, principal, session)
    job = session.get(Job, job_id)
    assert job is not None
    row = session.get(JobArchive, job_id) or JobArchive(
        job_id=job_id, organisation_id=principal.organisation_id
    )
    row.name = job.name
    row.archived_by = principal.user_id
    row.summary = _jsonable(summary)
    row.cells = _jsonable(cells)
    row.archived_at = func.now()
    session.add(row)
    session.commit()
    session.refresh(row)
    return _out(row, full=False)


@router.get("/job-archives", response_model=ArchiveList)
def list_archives(
    principal: UserDep,
    session: SessionDep,
    limit: int = Query(default=100, ge=1, le=1000),
    offset: int = Query(default=0, ge=0),
) -> dict[str, Any]:
    stmt = select(JobArchive).where(JobArchive.organisation_id == principal.organisation_id)
    total = session.scalar(select(func.count()).select_from(stmt.subquery())) or 0
    rows = session.scalars(stmt.order_by(JobArchive.job_id).limit(limit).offset(offset))
    return {"items": [_out(r, full=False) for r in rows], "total": total}


@router.get("/job-archives/{job_id:int}", response_model=ArchiveOut)
def get_archive(job_id: int, principal: UserDep, session: SessionDep) -> dict[str, Any]:
    row = session.get(JobArchive, job_id)
    if row is None or row.organisation_id != principal.organisation_id:
        raise ApiError(404, f"archive of job {job_id} not found")
    return _out(row, full=True)


def _jsonable(obj: Any) -> Any:
    import json

    from fastapi.encoders import jsonable_encoder

    return json.loads(json.dumps(jsonable_encoder(obj), allow_nan=True).replace("NaN", "null"))
