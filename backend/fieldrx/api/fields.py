"""Fields: GeoJSON Features in and out, validated boundaries, bulk import."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, HTTPException, Query, UploadFile
from geoalchemy2.shape import to_shape
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from fieldrx.api.common import ApiError, geom_to_geojson, get_scoped
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.fields import (
    FieldAnnotations,
    FieldCollection,
    FieldFeature,
    FieldFeatureIn,
    FieldImportOut,
    FieldPatch,
    FieldProps,
)
from fieldrx.auth.deps import Principal, SessionDep, UserDep, WriterDep
from fieldrx.db.geometry import shape_to_db
from fieldrx.db.models import Farm, Imagery
from fieldrx.db.models import Field as FieldRow
from fieldrx.geo.validate import BoundaryError, ValidBoundary, validate_boundary
from fieldrx.imagery import storage as imagery_storage
from fieldrx.services.evidence import delete_jobs, refuse_if_evidence

router = APIRouter(prefix="/fields", tags=["fields"], responses=ERRORS)

MAX_IMPORT_BYTES = 50 * 1024 * 1024


def field_feature(row: FieldRow) -> dict[str, Any]:
    return {
        "type": "Feature",
        "id": row.id,
        "geometry": geom_to_geojson(row.boundary),
        "bbox": list(to_shape(row.boundary).bounds),
        "properties": {
            "id": row.id,
            "name": row.name,
            "farm_id": row.farm_id,
            "crop": row.crop,
            "notes": row.notes,
            "area_m2": row.area_m2,
            "area_ha": row.area_m2 / 10_000.0,
            "utm_epsg": row.utm_epsg,
            "created_at": row.created_at.isoformat() if row.created_at else None,
        },
    }


def boundary_422(exc: BoundaryError, index: int | None = None) -> ApiError:
    body = exc.to_dict()
    message = body.pop("detail")
    if index is not None:
        body["feature_index"] = index
        message = f"feature {index}: {message}"
    return ApiError(422, message, **body)


def _check_farm(session: Session, farm_id: int | None, principal: Principal) -> None:
    if farm_id is not None:
        farm = session.get(Farm, farm_id)
        if farm is None or farm.organisation_id != principal.organisation_id:
            raise ApiError(422, f"farm {farm_id} not found", where="properties.farm_id")


def _new_field(principal: Principal, geometry: dict[str, Any], props: FieldProps) -> FieldRow:
    return _valid_field(principal, validate_boundary(geometry), props)


def _valid_field(principal: Principal, valid: ValidBoundary, props: FieldProps) -> FieldRow:
    return FieldRow(
        organisation_id=principal.organisation_id,
        farm_id=props.farm_id,
        name=props.name or "Unnamed field",
        crop=props.crop,
        notes=props.notes,
        boundary=shape_to_db(valid.geometry),
        utm_epsg=valid.utm_epsg,
        area_m2=valid.area_m2,
    )


@router.get("", response_model=FieldCollection)
def list_fields(
    principal: UserDep,
    session: SessionDep,
    bbox: str | None = Query(default=None, description="minlon,minlat,maxlon,maxlat"),
    farm_id: int | None = None,
    q: str | None = Query(default=None, description="case-insensitive name filter"),
    limit: int = Query(default=100, ge=1, le=1000),
    offset: int = Query(default=0, ge=0),
) -> dict[str, Any]:
    """All fields of the organisation as a GeoJSON FeatureCollection (paged, filterable)."""
    stmt = select(FieldRow).where(FieldRow.organisation_id == principal.organisation_id)
    if bbox:
        try:
            minx, miny, maxx, maxy = (float(v) for v in bbox.split(","))
        except ValueError:
            raise HTTPException(
                422, "bbox must be four numbers: minlon,minlat,maxlon,maxlat"
            ) from None
        if minx > maxx or miny > maxy:
            raise HTTPException(422, "bbox minimum is greater than its maximum")
        stmt = stmt.where(
            func.ST_Intersects(
                FieldRow.boundary, func.ST_MakeEnvelope(minx, miny, maxx, maxy, 4326)
            )
        )
    if farm_id is not None:
        stmt = stmt.where(FieldRow.farm_id == farm_id)
    if q:
        stmt = stmt.where(FieldRow.name.ilike(f"%{q}%"))
    total = session.scalar(select(func.count()).select_from(stmt.subquery())) or 0
    rows = session.scalars(stmt.order_by(FieldRow.id).limit(limit).offset(offset))
    return {
        "type": "FeatureCollection",
        "features": [field_feature(r) for r in rows],
        "total": total,
        "limit": limit,
        "offset": offset,
    }


@router.post("", status_code=201, response_model=FieldFeature)
def create_field(body: FieldFeatureIn, principal: WriterDep, session: SessionDep) -> dict[str, Any]:
    """Create a field from a GeoJSON Feature; the boundary is validated and oriented."""
    _check_farm(session, body.properties.farm_id, principal)
    try:
        row = _new_field(principal, body.geometry, body.properties)
    except BoundaryError as exc:
        raise boundary_422(exc) from exc
    session.add(row)
    session.commit()
    return field_feature(row)


def read_valid_fields(
    filename: str, data: bytes
) -> list[tuple[dict[str, Any], Any]] | tuple[int, BoundaryError]:
    """Read and validate every boundary of an upload (run in a worker process, see
    services.bounded): ``[(properties, ValidBoundary)]``, or ``(index, error)`` of the first
    invalid one. Raises ``FormatError``."""
    from fieldrx.formats.field_import import read_fields

    out = []
    for i, (props, geom) in enumerate(read_fields(filename, data)):
        try:
            out.append((props, validate_boundary(geom.__geo_interface__)))
        except BoundaryError as exc:
            return i, exc
    return out


@router.post("/import", status_code=201, response_model=FieldImportOut)
def import_fields(
    file: UploadFile,
    principal: WriterDep,
    session: SessionDep,
    farm_id: int | None = None,
) -> dict[str, Any]:
    """Bulk import from a GeoJSON FeatureCollection, KML or zipped Shapefile: all fields or none."""
    from fieldrx.formats import FormatError
    from fieldrx.services.bounded import run_bounded
    from fieldrx.settings import get_settings

    data = file.file.read(MAX_IMPORT_BYTES + 1)  # a sync endpoint: runs in the thread pool
    if len(data) > MAX_IMPORT_BYTES:
        raise HTTPException(413, f"file larger than {MAX_IMPORT_BYTES // 1024 // 1024} MB")
    _check_farm(session, farm_id, principal)
    try:
        items = run_bounded(
            read_valid_fields,
            file.filename or "upload",
            data,
            time_limit_s=get_settings().import_time_limit_s,
            what="the field import",
        )
    except FormatError as exc:
        raise ApiError(422, str(exc), where=file.filename) from exc
    if isinstance(items, tuple):
        raise boundary_422(items[1], items[0])
    if not items:
        raise ApiError(422, "the file contains no field boundaries", where=file.filename)
    rows = []
    for i, (props, valid) in enumerate(items):
        name = str(props.get("name") or props.get("Name") or props.get("NAME") or f"Field {i + 1}")
        fp = FieldProps(name=name[:200], farm_id=farm_id, crop=str(props.get("crop", ""))[:100])
        rows.append(_valid_field(principal, valid, fp))
    session.add_all(rows)
    session.commit()
    return {
        "type": "FeatureCollection",
        "features": [field_feature(r) for r in rows],
        "imported": len(rows),
    }


@router.get("/{field_id:int}", response_model=FieldFeature)
def get_field(field_id: int, principal: UserDep, session: SessionDep) -> dict[str, Any]:
    return field_feature(get_scoped(session, FieldRow, field_id, principal))


@router.get("/{field_id:int}/annotations", response_model=FieldAnnotations)
def get_field_annotations(field_id: int, principal: UserDep, session: SessionDep) -> dict[str, Any]:
    """What an import kept with the field: guidance lines, obstacles, routes, points."""
    row = get_scoped(session, FieldRow, field_id, principal)
    return {
        "type": "FeatureCollection",
        "features": row.features or [],
        "source_ref": row.source_ref,
    }


@router.patch("/{field_id:int}", response_model=FieldFeature)
def update_field(
    field_id: int, body: FieldPatch, principal: WriterDep, session: SessionDep
) -> dict[str, Any]:
    row = get_scoped(session, FieldRow, field_id, principal)
    if body.properties is not None:
        props = body.properties.model_dump(exclude_unset=True)
        if "farm_id" in props:
            _check_farm(session, props["farm_id"], principal)
        for key, value in props.items():
            setattr(row, key, value)
    if body.geometry is not None:
        try:
            valid = validate_boundary(body.geometry)
        except BoundaryError as exc:
            raise boundary_422(exc) from exc
        row.boundary = shape_to_db(valid.geometry)
        row.utm_epsg = valid.utm_epsg
        row.area_m2 = valid.area_m2
    row.updated_at = func.now()
    session.commit()  # StaleDataError (409, app.py) when a DELETE won the race before this
    fresh = session.get(FieldRow, field_id, populate_existing=True)
    if fresh is None:  # ... or after it
        raise ApiError(409, f"field {field_id} was deleted by another request meanwhile")
    return field_feature(fresh)


@router.delete("/{field_id:int}", status_code=204)
def delete_field(field_id: int, principal: WriterDep, session: SessionDep) -> None:
    """Delete the field, its plans and jobs; 409 while a job holds unarchived as-applied data."""
    field = get_scoped(session, FieldRow, field_id, principal)
    refuse_if_evidence(session, "field", field.id)
    delete_jobs(session, "field", field.id)
    cogs = session.scalars(select(Imagery.storage_key).where(Imagery.field_id == field.id)).all()
    session.delete(field)
    session.commit()
    imagery_storage.remove(cogs)  # the rows went with the field (cascade); now their files
