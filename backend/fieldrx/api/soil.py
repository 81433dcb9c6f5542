"""Soil samples of a field: import CSV / GeoJSON (all or nothing), list as GeoJSON, delete."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, HTTPException, Query, UploadFile

from fieldrx.agronomy.soil import SoilFormatError
from fieldrx.api.common import ApiError, get_scoped
from fieldrx.api.schemas.base import Deleted
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.soil import SampleCollection, SoilImportList, SoilImportResult
from fieldrx.auth.deps import SessionDep, UserDep, WriterDep
from fieldrx.db.models import Field
from fieldrx.services import soil as svc
from fieldrx.services.bounded import run_bounded
from fieldrx.settings import get_settings

router = APIRouter(prefix="/fields", tags=["soil"], responses=ERRORS)

MAX_BYTES = 20 * 1024 * 1024
MAX_ROWS = 50_000  # a 1 ha sampling grid on a 5,000 ha farm; more is abuse or a wrong file


def count_rows(name: str, data: bytes) -> int:
    """Upper bound on the rows (CSV lines, GeoJSON Features) of an upload, counted in C before
    any parsing so a million-row file is refused in milliseconds."""
    if name.lower().endswith((".geojson", ".json")):
        return data.count(b'"Feature"')
    return data.count(b"\n") + (0 if data.endswith(b"\n") else 1) - 1  # minus the header


@router.post("/{field_id:int}/soil-samples", status_code=201, response_model=SoilImportResult)
def import_samples(
    field_id: int,
    file: UploadFile,
    principal: WriterDep,
    session: SessionDep,
    skip_bad_rows: bool = Query(default=False, description="store the good rows, report the bad"),
    epsg: int | None = Query(default=None, description="EPSG code of x/y columns (else lon/lat)"),
    include_outside: bool = Query(
        default=False, description="also store samples lying outside the field (reported anyway)"
    ),
) -> dict[str, Any]:
    """Import samples. Any bad row rejects the whole file (422 listing row + column of every
    error) unless ``skip_bad_rows``; samples outside the field (beyond a 10 m tolerance) are
    reported with their distance and stored only with ``include_outside``; the same file
    twice on one field is refused (409)."""
    field = get_scoped(session, Field, field_id, principal)
    data = file.file.read(MAX_BYTES + 1)  # a sync endpoint: runs in the thread pool
    if len(data) > MAX_BYTES:
        raise HTTPException(413, f"file larger than {MAX_BYTES // 1024 // 1024} MB")
    name = file.filename or "upload.csv"
    n_rows = count_rows(name, data)
    if n_rows > MAX_ROWS:
        raise ApiError(
            422, f"the file has {n_rows} rows, more than {MAX_ROWS}; split it", where=name
        )
    try:
        result = run_bounded(
            svc.parse_for_field,
            field,
            name,
            data,
            epsg,
            skip_bad_rows,
            time_limit_s=get_settings().import_time_limit_s,
            what="the soil import",
        )
    except SoilFormatError as exc:
        raise ApiError(422, str(exc), where=name) from exc
    report = result.summary()
    if result.rejected:
        n = len(result.errors)
        first = "; ".join(str(e) for e in result.errors[:3])
        more = f" (and {n - 3} more)" if n > 3 else ""
        raise ApiError(
            422,
            f"{n} error(s), nothing imported: {first}{more}",
            errors=report["errors"],
            outside=report["outside"],
            imported=0,
        )
    try:
        content = svc.store_import(
            session, field, name, data, result, include_outside, principal.user_id
        )
    except svc.ImportRefused as exc:
        session.rollback()
        raise ApiError(exc.status, str(exc), **exc.extra) from exc
    session.commit()
    return content


@router.get("/{field_id:int}/soil-samples", response_model=SampleCollection)
def list_samples(field_id: int, principal: UserDep, session: SessionDep) -> dict[str, Any]:
    field = get_scoped(session, Field, field_id, principal)
    return svc.samples_geojson(svc.sample_rows(session, field.id))


@router.delete("/{field_id:int}/soil-samples", response_model=Deleted)
def delete_samples(field_id: int, principal: WriterDep, session: SessionDep) -> dict[str, int]:
    field = get_scoped(session, Field, field_id, principal)
    n = svc.delete_samples(session, field.id)
    session.commit()
    return {"deleted": n}


@router.get("/{field_id:int}/soil-imports", response_model=SoilImportList)
def list_imports(field_id: int, principal: UserDep, session: SessionDep) -> dict[str, Any]:
    """The field's uploads (file, digest, samples stored, outside rows), newest first."""
    field = get_scoped(session, Field, field_id, principal)
    return svc.list_imports(session, field.id)


@router.delete("/{field_id:int}/soil-imports/{import_id:int}", response_model=Deleted)
def delete_import(
    field_id: int, import_id: int, principal: WriterDep, session: SessionDep
) -> dict[str, int]:
    """Delete one upload and its samples."""
    field = get_scoped(session, Field, field_id, principal)
    n = svc.delete_import(session, field.id, import_id)
    if n is None:
        raise ApiError(404, f"field {field.id} has no soil import {import_id}", where="import_id")
    session.commit()
    return {"deleted": n}


@router.delete("/{field_id:int}/soil-samples/{sample_pk:int}", response_model=Deleted)
def delete_sample(
    field_id: int, sample_pk: int, principal: WriterDep, session: SessionDep
) -> dict[str, int]:
    """Delete one sample by its id (``properties.id`` in the list)."""
    field = get_scoped(session, Field, field_id, principal)
    if not svc.delete_sample(session, field.id, sample_pk):
        raise ApiError(404, f"field {field.id} has no soil sample {sample_pk}", where="sample_pk")
    session.commit()
    return {"deleted": 1}
