"""Soil samples of a field: import CSV / GeoJSON (all or nothing), list as GeoJSON, delete."""

from __future__ import annotations

from typing import Any, Literal

from fastapi import APIRouter, Form, HTTPException, Query, UploadFile
from fastapi.responses import Response
from pydantic import ValidationError

from fieldrx.agronomy.soil import SoilFormatError
from fieldrx.agronomy.soil_lab import Mapping
from fieldrx.api.common import ApiError, get_scoped
from fieldrx.api.schemas.base import Deleted
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.files import file_response
from fieldrx.api.schemas.soil import (
    SampleCollection,
    SoilImportList,
    SoilImportResult,
    SoilLabPreview,
    SoilMappingIn,
)
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


def _read_upload(file: UploadFile) -> tuple[str, bytes]:
    """The upload's name and bytes, refused (413/422) when too large or too long."""
    data = file.file.read(MAX_BYTES + 1)  # a sync endpoint: runs in the thread pool
    if len(data) > MAX_BYTES:
        raise HTTPException(413, f"file larger than {MAX_BYTES // 1024 // 1024} MB")
    name = file.filename or "upload.csv"
    n_rows = count_rows(name, data)
    if n_rows > MAX_ROWS:
        raise ApiError(
            422, f"the file has {n_rows} rows, more than {MAX_ROWS}; split it", where=name
        )
    return name, data


def _mapping(text: str | None) -> Mapping | None:
    """The ``mapping`` form field (JSON of ``SoilMappingIn``) as the parser's ``Mapping``."""
    if text is None or not text.strip():
        return None
    try:
        m = SoilMappingIn.model_validate_json(text)
    except ValidationError as exc:
        first = exc.errors()[0]
        loc = ".".join(str(p) for p in first["loc"])
        raise ApiError(
            422, f"mapping{'.' + loc if loc else ''}: {first['msg']}", where="mapping"
        ) from exc
    columns = {str(k): v for k, v in m.columns.items()}
    units = {str(k): v for k, v in m.units.items()}
    return Mapping(columns, units, m.epsg, m.bulk_density_g_cm3, m.n_form)


MAPPING_FORM = Form(
    default=None,
    description="JSON of SoilMappingIn; omitted: the mapping the preview suggests",
)


@router.post("/{field_id:int}/soil-imports/preview", response_model=SoilLabPreview, status_code=200)
def preview_lab_file(
    field_id: int,
    file: UploadFile,
    principal: WriterDep,
    session: SessionDep,
    mapping: str | None = MAPPING_FORM,
) -> dict[str, Any]:
    """Read a soil lab's CSV (``;`` or ``,``, decimal commas, German or English headers) and
    show what it would import with ``mapping`` (or the suggested one): the columns, units,
    coordinate systems to choose from, the converted rows, the rejected rows with their
    reason and the rows outside the field. Nothing is stored."""
    field = get_scoped(session, Field, field_id, principal)
    name, data = _read_upload(file)
    m = _mapping(mapping)
    try:
        return run_bounded(
            svc.lab_preview,
            field,
            name,
            data,
            m,
            svc.count_samples(session, field.id),
            time_limit_s=get_settings().import_time_limit_s,
            what="the soil file preview",
        )
    except SoilFormatError as exc:
        raise ApiError(422, str(exc), where=name) from exc


@router.post("/{field_id:int}/soil-imports", status_code=201, response_model=SoilImportResult)
def import_lab_file(
    field_id: int,
    file: UploadFile,
    principal: WriterDep,
    session: SessionDep,
    mapping: str | None = MAPPING_FORM,
    mode: Literal["append", "replace"] = Query(
        default="append", description="replace: delete the field's samples first"
    ),
    include_outside: bool = Query(
        default=False, description="also store samples lying outside the field"
    ),
    skip_rejected: bool = Query(
        default=False, description="store the good rows when some are rejected"
    ),
) -> dict[str, Any]:
    """Import a lab file as its preview showed it, in one transaction: a rejected row (unless
    ``skip_rejected``), a mapping problem, a file already imported or no sample in the
    field stores nothing (and deletes nothing in ``replace`` mode)."""
    field = get_scoped(session, Field, field_id, principal)
    name, data = _read_upload(file)
    m = _mapping(mapping)
    try:
        _, _, _, result = run_bounded(
            svc.lab_result,
            field,
            name,
            data,
            m,
            time_limit_s=get_settings().import_time_limit_s,
            what="the soil import",
        )
    except SoilFormatError as exc:
        raise ApiError(422, str(exc), where=name) from exc
    report = result.summary()
    if result.rejected or (result.errors and not skip_rejected):
        n = len(result.errors)
        first = "; ".join(str(e) for e in result.errors[:3])
        more = f" (and {n - 3} more)" if n > 3 else ""
        hint = "" if result.rejected else " (skip_rejected=true stores the good rows)"
        raise ApiError(
            422,
            f"{n} error(s), nothing imported: {first}{more}{hint}",
            errors=report["errors"],
            outside=report["outside"],
            imported=0,
        )
    try:
        content = svc.store_import(
            session,
            field,
            name,
            data,
            result,
            include_outside,
            principal.user_id,
            replace=mode == "replace",
        )
    except svc.ImportRefused as exc:
        session.rollback()
        raise ApiError(exc.status, str(exc), **exc.extra) from exc
    session.commit()
    return content


@router.get(
    "/{field_id:int}/soil-imports/example.csv",
    response_class=Response,
    responses=file_response("an example lab file with points inside the field", "text/csv"),
)
def example_lab_file(field_id: int, principal: UserDep, session: SessionDep) -> Response:
    """A lab file as German labs write it (``;``, decimal commas, Rechtswert/Hochwert in the
    field's ETRS89/UTM zone, Nmin kg/ha, P2O5/K2O mg/100 g, humus %), points inside the field:
    download, look at it, upload it."""
    field = get_scoped(session, Field, field_id, principal)
    text, epsg = svc.example_file(field)
    return Response(
        text.encode(),
        media_type="text/csv",
        headers={
            "Content-Disposition": f'attachment; filename="soil_lab_example_field{field.id}.csv"',
            "X-Coordinate-System": f"EPSG:{epsg}",
        },
    )


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
    name, data = _read_upload(file)
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
