"""The machine's side of jobs (device token only): list, download the package, report state.

The package is built by ``fieldrx.services.jobpackage.build_job_package`` and
served with its checksum as a strong ETag; ``If-None-Match``
with the same checksum answers 304, so an agent polls cheaply. Downloading a
job that was ``sent`` moves it to ``downloaded``.
"""

from __future__ import annotations

import gzip

from fastapi import APIRouter, Request
from fastapi.responses import Response
from sqlalchemy import select

from fieldrx.api.common import ApiError
from fieldrx.api.jobs import job_out
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.jobs import (
    DeviceJobList,
    DeviceStateIn,
    DeviceTokenRotated,
    JobOut,
    JobPackageOut,
    RawLogsRequested,
    RawLogStored,
)
from fieldrx.auth.deps import DeviceDep, Principal, SessionDep
from fieldrx.db.models import Job
from fieldrx.fleet.jobstate import change_state, lock_job
from fieldrx.services.jobpackage import build_job_package

router = APIRouter(prefix="/device", tags=["device"], responses=ERRORS)

ACTIVE = ("sent", "downloaded", "running", "paused")


def _my_job(session: SessionDep, job_id: int, principal: Principal) -> Job:
    job = session.get(Job, job_id)
    if (
        job is None
        or job.organisation_id != principal.organisation_id
        or job.machine_id != principal.machine_id
    ):
        raise ApiError(404, f"job {job_id} not found")
    return job


@router.get("/jobs", response_model=DeviceJobList)
def device_jobs(principal: DeviceDep, session: SessionDep) -> DeviceJobList:
    rows = list(
        session.scalars(
            select(Job)
            .where(
                Job.machine_id == principal.machine_id,
                Job.organisation_id == principal.organisation_id,
                Job.state.in_(ACTIVE),
            )
            .order_by(Job.id)
        )
    )
    return DeviceJobList(items=[job_out(j) for j in rows], total=len(rows))


@router.get(
    "/jobs/{job_id:int}/package",
    response_class=Response,
    responses={
        200: {
            "description": "the job package (gzip with Accept-Encoding: gzip); ETag = checksum",
            "content": {"application/json": {"schema": JobPackageOut.model_json_schema()}},
        },
        304: {"description": "not modified (If-None-Match carried the package's checksum)"},
    },
)
def job_package(
    job_id: int, request: Request, principal: DeviceDep, session: SessionDep
) -> Response:
    job = _my_job(session, job_id, principal)
    if job.state in ("planned", "completed", "aborted"):
        raise ApiError(409, f"job {job_id} is '{job.state}': only sent or active jobs download")
    try:
        pkg = build_job_package(session, job)
    except LookupError as exc:
        raise ApiError(409, f"job {job_id}: cannot build its package: {exc}") from exc
    body = pkg.to_json()
    etag = f'"{pkg.checksum}"'
    changed = False
    if job.package_checksum != pkg.checksum:
        job.package_checksum = pkg.checksum
        changed = True
    if job.state == "sent":
        changed |= change_state(session, job, "downloaded", machine_id=principal.machine_id)
    if changed:
        session.commit()
    inm = request.headers.get("if-none-match", "")
    if etag in [t.strip() for t in inm.split(",")] or inm.strip() == "*":
        return Response(status_code=304, headers={"ETag": etag})
    headers = {"ETag": etag, "Cache-Control": "no-cache", "Vary": "Accept-Encoding"}
    if "gzip" in request.headers.get("accept-encoding", ""):
        body = gzip.compress(body, compresslevel=6, mtime=0)
        headers["Content-Encoding"] = "gzip"
    return Response(content=body, media_type="application/json", headers=headers)


@router.post("/jobs/{job_id:int}/state", response_model=JobOut)
def device_state(
    job_id: int, body: DeviceStateIn, principal: DeviceDep, session: SessionDep
) -> JobOut:
    job = _my_job(session, job_id, principal)
    lock_job(session, job)
    change_state(session, job, body.state, machine_id=principal.machine_id, note=body.note)
    session.commit()
    return job_out(job)


@router.get("/raw-logs/requested", response_model=RawLogsRequested)
def raw_logs_requested(principal: DeviceDep, session: SessionDep) -> dict[str, list[int]]:
    """Jobs of this machine whose full 10 Hz log the office asked for (thin uplink; the agent
    answers with ``PUT /device/jobs/{id}/raw-log``: ``fieldrx-edge upload-log``)."""
    from fieldrx.fleet import rawlogs

    ids = session.scalars(
        select(Job.id).where(
            Job.machine_id == principal.machine_id,
            Job.organisation_id == principal.organisation_id,
        )
    )
    return {"job_ids": [j for j in ids if rawlogs.requested(principal.organisation_id, j)]}


@router.put("/jobs/{job_id:int}/raw-log", response_model=RawLogStored)
async def upload_raw_log(
    job_id: int, request: Request, principal: DeviceDep, session: SessionDep
) -> dict[str, object]:
    """The job's full 10 Hz log (gzip of JSON lines, one record per fix) from the tractor."""
    from starlette.concurrency import run_in_threadpool

    from fieldrx.fleet import rawlogs
    from fieldrx.settings import get_settings

    job = _my_job(session, job_id, principal)
    limit = get_settings().raw_log_max_bytes
    body = bytearray()
    async for chunk in request.stream():
        body.extend(chunk)
        if len(body) > limit:
            raise ApiError(413, f"raw log larger than {limit} bytes (FIELDRX_RAW_LOG_MAX_BYTES)")
    try:
        lines = await run_in_threadpool(rawlogs.store, job.organisation_id, job.id, bytes(body))
    except ValueError as exc:
        raise ApiError(422, f"job {job_id}: {exc}") from exc
    return {"job_id": job.id, "bytes": len(body), "records": lines}


@router.post("/token", status_code=201, response_model=DeviceTokenRotated)
def rotate_token(principal: DeviceDep, session: SessionDep) -> DeviceTokenRotated:
    """Rotate the machine's own device token: a new one (shown once) with a fresh expiry;
    the one used for this call is revoked. The agent stores the new token before using it."""
    from fieldrx.auth.service import issue_device_token, token_expiry

    assert principal.machine_id is not None
    token = issue_device_token(session, principal.machine_id, principal.organisation_id)
    session.commit()
    return DeviceTokenRotated(
        machine_id=principal.machine_id, token=token, expires_at=token_expiry(session, token)
    )
