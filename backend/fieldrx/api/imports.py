"""Imports of other software's files: ISO 11783-10 TASKDATA (preview, then confirm).

``POST /imports/isoxml`` with multipart ``files`` (a TASKDATA zip, or the
TASKDATA.XML with its .BIN/.XML files): without ``confirm`` it answers with
a preview (what would be created, what is skipped and why) and the upload's
SHA-256; nothing is stored. Sending the same files again with
``confirm=<sha256>`` stores everything in one transaction, or nothing (a large
upload, or any with ``background=true``: as an ``import`` task, 202). The
handler is a plain ``def`` so parsing runs in the threadpool, not on the
event loop.
"""

from __future__ import annotations

import hashlib
import shutil
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
from fastapi import APIRouter, Query, Response, UploadFile
from fastapi.responses import JSONResponse
from sqlalchemy.orm import Session

from fieldrx.api.common import ApiError
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.imports import (
    AsAppliedTableImportOut,
    IsoxmlImportOut,
    RxShapefileImportOut,
    TimelogImportOut,
)
from fieldrx.api.schemas.tasks import TaskOut
from fieldrx.auth.deps import Principal, SessionDep, WriterDep
from fieldrx.errors import TooLarge
from fieldrx.formats import FormatError
from fieldrx.geo import PlanningError
from fieldrx.geo.planning.kinematics import DEFAULT_HEADLAND_PASSES
from fieldrx.services import imports as svc
from fieldrx.services import spool
from fieldrx.services import timelog_import as timelog_svc
from fieldrx.services.bounded import run_bounded
from fieldrx.services.plans import PlanParams, check_plan_cost
from fieldrx.settings import get_settings

router = APIRouter(prefix="/imports", tags=["imports"], responses=ERRORS)

MAX_UPLOAD_BYTES = 100 * 1024 * 1024
STORED = "stored (confirm matched the preview); 200 is the preview"


def _spool_files(files: list[UploadFile], folder: Path) -> tuple[list[tuple[str, str]], str, str]:
    """The uploads written to ``folder`` in chunks (never whole in memory), the same digest
    as ``_files`` (the preview's sha256) and their names."""
    spooled: list[tuple[str, str]] = []
    digest = hashlib.sha256()
    total = 0
    for i, f in enumerate(sorted(files, key=lambda u: u.filename or "")):
        name = (f.filename or "upload").replace("\\", "/").rsplit("/", 1)[-1]
        path = folder / f"{i:04d}.upload"
        try:
            n, sha = spool.spool(f.file, path, MAX_UPLOAD_BYTES, total)
        except TooLarge as exc:
            raise ApiError(413, exc.message) from exc
        total += n
        digest.update(name.encode() + b"\0" + bytes.fromhex(sha))
        spooled.append((name, str(path)))
    names = ", ".join(sorted(f.filename or "upload" for f in files))
    return spooled, digest.hexdigest(), names


@router.post(
    "/isoxml",
    response_model=IsoxmlImportOut,
    responses={
        201: {"model": IsoxmlImportOut, "description": "stored (confirm matched the preview)"},
        202: {"model": TaskOut, "description": "confirm queued as an import task"},
    },
)
def import_isoxml(
    files: list[UploadFile],
    response: Response,
    principal: WriterDep,
    session: SessionDep,
    confirm: str | None = Query(default=None, description="the preview's sha256"),
    swath_width_m: float = Query(default=PlanParams.swath_width_m, gt=0, le=100),
    cell_length_m: float = Query(default=PlanParams.cell_length_m, gt=0, le=500),
    headland_passes: int = Query(default=DEFAULT_HEADLAND_PASSES, ge=0, le=20),
    density_kg_l: float | None = Query(
        default=None,
        gt=0,
        le=5,
        description="density of a volume-rate product (kg/l): imports l/ha grids as kg/ha",
    ),
    background: bool | None = Query(
        default=None,
        description="confirm as a background task (202 + task); default: when the upload "
        "is larger than FIELDRX_IMPORT_BACKGROUND_BYTES",
    ),
) -> Any:
    """Preview (no ``confirm``) or store (``confirm`` = the preview's sha256) a TASKDATA set.

    The upload is spooled to disk; inflating, parsing and (on confirm) planning and storing
    run in a worker process (FIELDRX_IMPORT_TIME_LIMIT_S for a preview,
    FIELDRX_PLAN_TIME_LIMIT_S for a confirm; 422 past it, nothing stored). A large confirm
    (or any, with ``background=true``) runs as a task of kind ``import`` instead: 202 with
    the task, whose progress names the stage and whose result holds ``created`` and
    ``skipped`` once it succeeded (a failure stores nothing and fails the task)."""
    settings = get_settings()
    params = PlanParams(
        swath_width_m=swath_width_m, cell_length_m=cell_length_m, headland_passes=headland_passes
    )
    if confirm is not None:
        try:  # parameters no field can take are refused before the upload is read
            check_plan_cost(0.0, params)
        except PlanningError as exc:
            raise ApiError(422, str(exc), where="cell_length_m") from exc
    session.rollback()  # no transaction of the server stays open while the worker runs
    with spool.spool_dir() as folder:
        spooled, sha, names = _spool_files(files, folder)
        confirmed = confirm is not None and confirm == sha
        size = sum(Path(path).stat().st_size for _, path in spooled)
        if confirmed and (
            background or (background is None and size > settings.import_background_bytes)
        ):
            return _queue_import(session, principal, spooled, names, sha, params, density_kg_l)
        limit = settings.plan_time_limit_s if confirmed else settings.import_time_limit_s
        req = svc.IsoxmlRequest(
            database_url=session.get_bind().engine.url.render_as_string(hide_password=False),
            files=spooled,
            source_name=names,
            organisation_id=principal.organisation_id,
            user_id=principal.user_id,
            params=params,
            confirm=confirmed,
            time_limit_s=limit,
            density_kg_l=density_kg_l,
        )
        try:
            out = run_bounded(
                svc.isoxml_in_worker, req, time_limit_s=limit, what="the ISOXML import"
            )
        except (FormatError, PlanningError) as exc:
            raise ApiError(422, str(exc), where=names) from exc
    body: dict[str, Any] = {"sha256": sha, "preview": out["preview"]}
    if confirm is None:
        body["stored"] = False
        return body
    if not confirmed:  # checked after the preview: a broken upload is a 422 either way
        raise ApiError(409, "confirm does not match this upload's sha256: preview it again")
    body["stored"] = True
    body["created"] = out["created"]
    response.status_code = 201
    return body


def _queue_import(
    session: Session,
    principal: Principal,
    spooled: list[tuple[str, str]],
    names: str,
    sha: str,
    params: PlanParams,
    density_kg_l: float | None,
) -> JSONResponse:
    """Move the spooled upload to a shared incoming folder and queue an ``import`` task on
    it (``tasks.imports``: the task removes the folder when it ends)."""
    from fieldrx.api.tasks import queue_task
    from fieldrx.imagery import storage

    incoming = storage.incoming_path()
    incoming.mkdir()
    try:
        stored = []
        for i, (name, path) in enumerate(spooled):
            shutil.move(path, incoming / f"{i:04d}.upload")
            stored.append([name, f"{i:04d}.upload"])
        task_params = {
            "incoming": incoming.name,
            "files": stored,
            "source_name": names,
            "sha256": sha,
            "plan": asdict(params),
            "density_kg_l": density_kg_l,
        }
        return queue_task(session, principal, "import", task_params)
    except BaseException:
        session.rollback()
        shutil.rmtree(incoming, ignore_errors=True)
        raise


@router.post(
    "/prescription-shapefile",
    response_model=RxShapefileImportOut,
    responses={
        201: {"model": RxShapefileImportOut, "description": "stored (confirm matched the preview)"}
    },
)
def import_prescription_shapefile(
    file: UploadFile,
    response: Response,
    principal: WriterDep,
    session: SessionDep,
    field_id: int = Query(description="the field the prescription is for"),
    rate_column: str | None = Query(default=None, description="attribute holding the rate"),
    unit: str = Query(default="kg/ha", description="unit of the rate column"),
    default_rate_kg_ha: float = Query(default=0.0, ge=0, description="rate outside polygons"),
    density_kg_l: float | None = Query(
        default=None, gt=0, le=5, description="product density (kg/l) for a volume-rate unit"
    ),
    name: str = Query(default="", max_length=200),
    product: str = Query(default="fertilizer", max_length=200),
    confirm: str | None = Query(default=None, description="the preview's sha256"),
    swath_width_m: float = Query(default=PlanParams.swath_width_m, gt=0, le=100),
    cell_length_m: float = Query(default=PlanParams.cell_length_m, gt=0, le=500),
    headland_passes: int = Query(default=DEFAULT_HEADLAND_PASSES, ge=0, le=20),
) -> dict[str, Any]:
    """A zipped prescription Shapefile with an attribute-mapping step (preview, then confirm).

    Without ``rate_column`` the preview lists the numeric columns and a
    suggestion; with it, the rates in kg/ha. ``confirm`` (the preview's
    sha256) builds a plan on the field and stores version 1.
    """
    from geoalchemy2.shape import to_shape

    from fieldrx.api.common import get_scoped
    from fieldrx.db.models import Field as FieldRow
    from fieldrx.formats.field_import import read_shapefile_zip_fields
    from fieldrx.formats.rx_shapefile import (
        UNITS,
        VOLUME_UNITS,
        numeric_columns,
        rx_from_items,
        suggest_rate_column,
    )
    from fieldrx.services.import_checks import placement

    fld = get_scoped(session, FieldRow, field_id, principal)
    data = file.file.read(MAX_UPLOAD_BYTES + 1)
    if len(data) > MAX_UPLOAD_BYTES:
        raise ApiError(413, f"upload larger than {MAX_UPLOAD_BYTES // 1024 // 1024} MB")
    fname = file.filename or "upload.zip"
    try:
        items = read_shapefile_zip_fields(data)
    except FormatError as exc:
        raise ApiError(422, f"{fname}: {exc}", where=fname) from exc
    columns = numeric_columns(items)
    sha = hashlib.sha256(data).hexdigest()
    body: dict[str, Any] = {
        "sha256": sha,
        "features": len(items),
        "numeric_columns": columns,
        "suggested_rate_column": suggest_rate_column(columns),
        "units": sorted(UNITS) + sorted(VOLUME_UNITS),
        "stored": False,
    }
    if rate_column is None:
        if confirm is not None:
            raise ApiError(422, "confirm needs rate_column (the mapping step)", where="rate_column")
        return body
    try:
        rx = rx_from_items(
            items,
            rate_column,
            unit,
            default_rate_kg_ha,
            name or f"{fname} ({rate_column})",
            product,
            density_kg_l,
        )
    except FormatError as exc:
        raise ApiError(422, f"{fname}: {exc}", where=rate_column) from exc
    rates = [r for r, _ in rx.zones]
    body["mapping"] = {
        "rate_column": rate_column,
        "unit": unit,
        "min_rate_kg_ha": min(rates, default=0.0),
        "max_rate_kg_ha": max(rates, default=0.0),
        "default_rate_kg_ha": default_rate_kg_ha,
    }
    if rx.zones:
        place = placement(to_shape(fld.boundary), fld.utm_epsg, rx.coverage())
        body["mapping"]["overlap_pct"] = place.overlap_pct
        body["mapping"]["distance_m"] = round(place.distance_m, 1)
        body["mapping"]["warning"] = place.describe(f"the zones of {fname}", fld.name)
    if confirm is None:
        return body
    if body["mapping"].get("distance_m"):
        raise ApiError(422, str(body["mapping"]["warning"]), where=fname)
    if confirm != sha:
        raise ApiError(409, "confirm does not match this upload's sha256: preview it again")
    params = PlanParams(
        swath_width_m=swath_width_m, cell_length_m=cell_length_m, headland_passes=headland_passes
    )
    source = {
        "file": fname,
        "kind": "shapefile",
        "rate_column": rate_column,
        "unit": unit,
        "density_kg_l": density_kg_l,
    }
    limit = get_settings().plan_time_limit_s
    req = svc.RxStoreRequest(
        database_url=session.get_bind().engine.url.render_as_string(hide_password=False),
        rx=rx,
        field_id=fld.id,
        params=params,
        organisation_id=principal.organisation_id,
        user_id=principal.user_id,
        source=source,
        time_limit_s=limit,
    )
    field_id, area_m2 = fld.id, fld.area_m2
    session.rollback()  # no transaction of the server stays open while the worker plans
    try:
        check_plan_cost(area_m2, params)
        rx_id, plan_id = run_bounded(
            svc.store_prescription_in_worker, req, time_limit_s=limit, what="the import"
        )
    except PlanningError as exc:
        raise ApiError(422, str(exc)) from exc
    body["stored"] = True
    body["created"] = {"prescription_id": rx_id, "plan_id": plan_id, "field_id": field_id}
    response.status_code = 201
    return body


@router.post(
    "/timelog",
    response_model=TimelogImportOut,
    responses={
        201: {"model": TimelogImportOut, "description": "stored (confirm matched the preview)"}
    },
)
def import_timelog(
    files: list[UploadFile],
    response: Response,
    principal: WriterDep,
    session: SessionDep,
    prescription_id: int = Query(description="the prescription the as-applied data belongs to"),
    width_m: float | None = Query(
        default=None, gt=0, le=100, description="working width; default DDI 67 from the log"
    ),
    confirm: str | None = Query(default=None, description="the preview's sha256"),
) -> dict[str, Any]:
    """ISO 11783-10 TimeLogs (TLGxxxxx.XML + .BIN, zipped or loose) as a completed job.

    The preview lists each log's records, time span, positions and the DDIs
    used and ignored; ``confirm`` (the preview's sha256) stores the records as
    a job on the prescription, so the report (target vs applied, eq. 18) works.
    The upload is spooled to disk; inflating, decoding and storing run in a worker
    process (FIELDRX_IMPORT_TIME_LIMIT_S; 422 past it, nothing stored).
    """
    from fieldrx.api.common import get_scoped
    from fieldrx.db.models import Prescription

    settings = get_settings()
    rx_id = int(get_scoped(session, Prescription, prescription_id, principal).id)
    session.rollback()  # no transaction of the server stays open while the worker runs
    with spool.spool_dir() as folder:
        spooled, sha, names = _spool_files(files, folder)
        req = timelog_svc.TimelogRequest(
            database_url=session.get_bind().engine.url.render_as_string(hide_password=False),
            files=spooled,
            source_name=names,
            prescription_id=rx_id,
            organisation_id=principal.organisation_id,
            user_id=principal.user_id,
            width_m=width_m,
            confirm=confirm is not None and confirm == sha,
            time_limit_s=settings.import_time_limit_s,
        )
        try:
            out = run_bounded(
                timelog_svc.timelog_in_worker,
                req,
                time_limit_s=settings.import_time_limit_s,
                what="the TimeLog import",
            )
        except FormatError as exc:
            raise ApiError(422, str(exc), where=names) from exc
    body: dict[str, Any] = {
        "sha256": sha,
        "timelogs": out["timelogs"],
        "stored": False,
        "width_m": out["width_m"],
        "refused": out["refused"],
    }
    if confirm is None:
        return body
    if not req.confirm:  # checked after the preview: a broken upload is a 422 either way
        raise ApiError(409, "confirm does not match this upload's sha256: preview it again")
    body["stored"] = True
    body["created"] = out["created"]
    response.status_code = 201
    return body


@router.post(
    "/as-applied-table",
    response_model=AsAppliedTableImportOut,
    responses={
        201: {
            "model": AsAppliedTableImportOut,
            "description": "stored (confirm matched the preview)",
        }
    },
)
def import_asapplied_table(
    file: UploadFile,
    response: Response,
    principal: WriterDep,
    session: SessionDep,
    prescription_id: int = Query(description="the prescription the as-applied data belongs to"),
    width_m: float | None = Query(default=None, gt=0, le=100, description="working width"),
    rate_column: str | None = Query(default=None, description="applied rate column"),
    unit: str = Query(default="kg/ha"),
    target_column: str | None = None,
    speed_column: str | None = None,
    speed_unit: str = Query(default="m/s"),
    time_column: str | None = None,
    work_state_column: str | None = None,
    lon_column: str | None = None,
    lat_column: str | None = None,
    interval_s: float = Query(default=1.0, gt=0, le=3600),
    confirm: str | None = Query(default=None, description="the preview's sha256"),
) -> dict[str, Any]:
    """Another terminal's as-applied Shapefile (zip) or CSV, with an attribute-mapping step.

    Without ``rate_column`` the preview lists the columns and suggestions;
    with the mapping it shows the decoded records; ``confirm`` (the preview's
    sha256, plus ``width_m``) stores them as a completed job on the prescription.
    """
    import time

    from fieldrx.api.common import get_scoped
    from fieldrx.db.models import Prescription
    from fieldrx.formats.asapplied_table import (
        ColumnMap,
        read_table,
        table_columns,
        to_timelog,
    )

    rx = get_scoped(session, Prescription, prescription_id, principal)
    data = file.file.read(MAX_UPLOAD_BYTES + 1)
    if len(data) > MAX_UPLOAD_BYTES:
        raise ApiError(413, f"upload larger than {MAX_UPLOAD_BYTES // 1024 // 1024} MB")
    fname = file.filename or "upload"
    sha = hashlib.sha256(data).hexdigest()
    try:
        table = read_table(fname, data)
    except FormatError as exc:
        raise ApiError(422, str(exc), where=fname) from exc
    body: dict[str, Any] = {"sha256": sha, **table_columns(table), "stored": False}
    if rate_column is None:
        if confirm is not None:
            raise ApiError(422, "confirm needs rate_column (the mapping step)", where="rate_column")
        return body
    try:
        mapping = ColumnMap(
            rate_column=rate_column,
            unit=unit,
            target_column=target_column,
            speed_column=speed_column,
            speed_unit=speed_unit,
            time_column=time_column,
            work_state_column=work_state_column,
            lon_column=lon_column,
            lat_column=lat_column,
            interval_s=interval_s,
        )
        log = to_timelog(table, mapping, start_t=float(int(time.time())))
    except FormatError as exc:
        raise ApiError(422, f"{fname}: {exc}", where=fname) from exc
    rates = log.series(7, 0.01)
    body["mapping"] = {
        "records": len(log),
        "mean_applied_rate_kg_ha": float(np.mean(rates)),
        "mean_speed_m_s": float(np.mean(log.series(397, 0.001))),
        "times": "from " + time_column if time_column else f"every {interval_s} s in file order",
    }
    if confirm is None:
        return body
    if confirm != sha:
        raise ApiError(409, "confirm does not match this upload's sha256: preview it again")
    if width_m is None:
        raise ApiError(422, "give the working width width_m", where="width_m")
    try:
        created = timelog_svc.store_timelogs(
            session, [log], rx, principal.organisation_id, principal.user_id, width_m, fname
        )
    except FormatError as exc:
        session.rollback()
        raise ApiError(422, str(exc), where=fname) from exc
    session.commit()
    body["stored"] = True
    body["created"] = created
    response.status_code = 201
    return body
