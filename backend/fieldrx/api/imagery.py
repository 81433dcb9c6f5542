"""Imagery: GeoTIFF upload per field (stored as COG), listing, deletion and PNG tiles.

Uploads are received to disk in chunks and converted in a separate process with a time
limit (``imagery.ingest``); the endpoints are plain ``def`` so FastAPI runs them in its
thread pool, off the event loop. Large uploads need the server's request-size limit for
this route raised to ``FIELDRX_IMAGERY_MAX_UPLOAD_BYTES``.
"""

from __future__ import annotations

import datetime as dt
from typing import Any, Literal

import numpy as np
from fastapi import APIRouter, File, Form, Query, Request, Response, UploadFile
from geoalchemy2.shape import to_shape
from shapely import wkb
from sqlalchemy import select

from fieldrx.agronomy.cells import CellTable
from fieldrx.agronomy.zones import ZoneError, zone_cell_values
from fieldrx.api.common import ApiError, geom_to_geojson, get_scoped
from fieldrx.api.prescriptions import BAD_INPUT
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.files import file_response
from fieldrx.api.schemas.imagery import (
    ImageryList,
    ImageryOut,
    ImageryRxIn,
    ImageryUploadOut,
    ZonesIn,
)
from fieldrx.api.schemas.prescriptions import PrescriptionOut
from fieldrx.api.schemas.tasks import QUEUED
from fieldrx.auth.deps import SessionDep, UserDep, WriterDep
from fieldrx.db.models import Field as FieldRow
from fieldrx.db.models import Imagery, Machine, Plan
from fieldrx.imagery import ImageryError, storage
from fieldrx.imagery.ingest import IngestSpec, ingest
from fieldrx.imagery.stats import cell_ndvi
from fieldrx.imagery.tiles import render_tile
from fieldrx.services.imagery import imagery_row
from fieldrx.services.prescriptions import create as rx_create
from fieldrx.services.prescriptions import meter as rx_meter
from fieldrx.services.prescriptions import versions as rx_versions
from fieldrx.settings import get_settings

router = APIRouter(tags=["imagery"], responses=ERRORS)

CHUNK = 1024 * 1024
MAX_ZOOM = 24


def imagery_item(row: Imagery) -> dict[str, Any]:
    foot = to_shape(row.footprint)
    return {
        "id": row.id,
        "field_id": row.field_id,
        "kind": row.kind,
        "name": row.name,
        "filename": row.filename,
        "acquired_on": row.acquired_on.isoformat() if row.acquired_on else None,
        "source_crs": row.source_crs,
        "resolution_m": row.resolution_m,
        "width": row.width,
        "height": row.height,
        "band_count": row.band_count,
        "dtype": row.dtype,
        "bands": row.bands,
        "nodata": row.nodata,
        "size_bytes": row.size_bytes,
        "bounds": list(foot.bounds),
        "footprint": geom_to_geojson(foot),
        "tiles": f"/api/v1/tiles/imagery/{row.id}/{{z}}/{{x}}/{{y}}.png",
        "created_at": row.created_at.isoformat() if row.created_at else None,
    }


def _receive(upload: UploadFile, limit: int) -> Any:
    """Copy the upload to the incoming folder in chunks; 413 beyond ``limit`` bytes."""
    path = storage.incoming_path()
    total = 0
    try:
        with open(path, "wb") as out:
            while chunk := upload.file.read(CHUNK):
                total += len(chunk)
                if total > limit:
                    raise ApiError(
                        413,
                        f"the upload exceeds the imagery limit of {limit:,} bytes",
                        where="file",
                    )
                out.write(chunk)
    except BaseException:
        path.unlink(missing_ok=True)
        raise
    if total == 0:
        path.unlink(missing_ok=True)
        raise ApiError(422, "the uploaded file is empty", where="file")
    return path


@router.post(
    "/fields/{field_id:int}/imagery",
    status_code=201,
    response_model=ImageryUploadOut,
    responses=QUEUED,
)
def upload_imagery(
    field_id: int,
    principal: WriterDep,
    session: SessionDep,
    file: UploadFile = File(..., description="a GeoTIFF (any CRS)"),
    kind: Literal["orthophoto", "ndvi", "multispectral"] = Form(...),
    name: str = Form(default="", max_length=200),
    acquired_on: dt.date | None = Form(default=None),
    red_band: int | None = Form(
        default=None, ge=1, description="multispectral: red band (1-based)"
    ),
    nir_band: int | None = Form(
        default=None, ge=1, description="multispectral: NIR band (1-based)"
    ),
    background: bool | None = Query(
        default=None,
        description="convert in a `fieldrx worker` and answer 202 with the task; default: "
        "only uploads larger than FIELDRX_IMAGERY_BACKGROUND_BYTES",
    ),
) -> Any:
    """Validate the GeoTIFF, convert it to a Cloud-Optimized GeoTIFF and record it.

    422 for a non-TIFF, an unreadable or non-georeferenced raster, one that does not overlap
    the field, a band count that does not fit the kind, or a header claiming more pixels
    than ``FIELDRX_IMAGERY_MAX_PIXELS``; nothing is stored then. A large upload (or any,
    with ``background=true``) is converted in the background: 202 with the task, whose
    ``result_url`` is the image (the same checks then fail the task with the same message).
    """
    field = get_scoped(session, FieldRow, field_id, principal)
    settings = get_settings()
    incoming = _receive(file, settings.imagery_max_upload_bytes)
    size = incoming.stat().st_size
    if background or (background is None and size > settings.imagery_background_bytes):
        return _queue_ingest(
            session,
            principal,
            incoming,
            {
                "field_id": field.id,
                "kind": kind,
                "name": name,
                "filename": (file.filename or "")[:255],
                "acquired_on": acquired_on.isoformat() if acquired_on else None,
                "red_band": red_band,
                "nir_band": nir_band,
                "size_bytes": size,
            },
        )
    key = storage.new_key(principal.organisation_id)
    dst = storage.path_for(key)
    dst.parent.mkdir(parents=True, exist_ok=True)
    spec = IngestSpec(
        kind=kind,
        field_wkb=wkb.dumps(to_shape(field.boundary)),
        utm_epsg=field.utm_epsg,
        red_band=red_band,
        nir_band=nir_band,
        max_pixels=settings.imagery_max_pixels,
        max_expansion=settings.imagery_max_expansion,
        acquired_on=acquired_on.isoformat() if acquired_on else None,
    )
    try:
        try:
            res = ingest(
                incoming,
                dst,
                spec,
                settings.imagery_timeout_s,
                slot_wait_s=settings.import_time_limit_s,
            )
        except ImageryError as exc:
            raise ApiError(422, str(exc), where="file") from exc
        row = imagery_row(
            organisation_id=principal.organisation_id,
            field_id=field.id,
            kind=kind,
            name=name,
            filename=file.filename or "",
            storage_key=key,
            res=res,
            created_by=principal.user_id,
        )
        session.add(row)
        session.commit()
    except BaseException:
        session.rollback()
        dst.unlink(missing_ok=True)
        raise
    finally:
        incoming.unlink(missing_ok=True)
    out = imagery_item(row)
    out["overlap_share"] = round(res.overlap_share, 4)
    out["warnings"] = res.warnings
    return out


def _queue_ingest(
    session: SessionDep, principal: WriterDep, incoming: Any, params: dict[str, Any]
) -> Response:
    """Hand the received upload to an imagery task (the task removes it when it ends)."""
    from fieldrx.api.tasks import queue_task

    try:
        return queue_task(session, principal, "imagery", {**params, "incoming": incoming.name})
    except BaseException:
        session.rollback()
        incoming.unlink(missing_ok=True)
        raise


@router.get("/fields/{field_id:int}/imagery", response_model=ImageryList)
def list_field_imagery(
    field_id: int, principal: UserDep, session: SessionDep, kind: str | None = None
) -> dict[str, Any]:
    """The field's images, newest acquisition first (then newest upload)."""
    get_scoped(session, FieldRow, field_id, principal)
    stmt = select(Imagery).where(
        Imagery.field_id == field_id, Imagery.organisation_id == principal.organisation_id
    )
    if kind is not None:
        stmt = stmt.where(Imagery.kind == kind)
    rows = session.scalars(
        stmt.order_by(
            Imagery.acquired_on.desc().nulls_last(), Imagery.created_at.desc(), Imagery.id.desc()
        )
    ).all()
    return {"items": [imagery_item(r) for r in rows], "total": len(rows)}


@router.get("/imagery", response_model=ImageryList)
def list_imagery(
    principal: UserDep, session: SessionDep, kind: str | None = None
) -> dict[str, Any]:
    """All images of the organisation (the map's imagery picker)."""
    stmt = select(Imagery).where(Imagery.organisation_id == principal.organisation_id)
    if kind is not None:
        stmt = stmt.where(Imagery.kind == kind)
    rows = session.scalars(
        stmt.order_by(
            Imagery.acquired_on.desc().nulls_last(), Imagery.created_at.desc(), Imagery.id.desc()
        )
    ).all()
    return {"items": [imagery_item(r) for r in rows], "total": len(rows)}


@router.get("/imagery/{imagery_id:int}", response_model=ImageryOut)
def get_imagery(imagery_id: int, principal: UserDep, session: SessionDep) -> dict[str, Any]:
    return imagery_item(get_scoped(session, Imagery, imagery_id, principal))


@router.delete("/imagery/{imagery_id:int}", status_code=204)
def delete_imagery(imagery_id: int, principal: WriterDep, session: SessionDep) -> None:
    """Delete the row, then the COG (a failed commit keeps both)."""
    row = get_scoped(session, Imagery, imagery_id, principal)
    path = storage.path_for(row.storage_key)
    session.delete(row)
    session.commit()
    path.unlink(missing_ok=True)


@router.get(
    "/tiles/imagery/{imagery_id:int}/{z:int}/{x:int}/{y:int}.png",
    response_class=Response,
    responses={
        **file_response("a 256 px PNG tile", "image/png"),
        204: {"description": "the image does not reach this tile"},
        304: {"description": "not modified (If-None-Match)"},
    },
)
def imagery_tile(
    imagery_id: int,
    z: int,
    x: int,
    y: int,
    request: Request,
    principal: UserDep,
    session: SessionDep,
) -> Response:
    """A 256 px web-mercator PNG tile; 204 where the image does not reach the tile.

    Images never change once stored (a new upload is a new id), so tiles carry a strong
    ETag and a day of private caching.
    """
    row = get_scoped(session, Imagery, imagery_id, principal)
    if not 0 <= z <= MAX_ZOOM:
        raise ApiError(422, f"zoom must be 0..{MAX_ZOOM}, got {z}")
    if not (0 <= x < (1 << z) and 0 <= y < (1 << z)):
        raise ApiError(422, f"tile {z}/{x}/{y} does not exist (x and y must be < {1 << z})")
    etag = f'"img-{row.id}-{z}-{x}-{y}"'
    headers = {"ETag": etag, "Cache-Control": "private, max-age=86400"}
    if request.headers.get("if-none-match") == etag:
        return Response(status_code=304, headers=headers)
    path = storage.path_for(row.storage_key)
    kind, bands = row.kind, dict(row.bands)
    session.close()  # do not hold a pooled connection while GDAL reads
    if not path.is_file():
        raise ApiError(404, f"imagery {imagery_id}: the stored raster is missing")
    data = render_tile(path, kind, bands, z, x, y)
    if data is None:
        return Response(status_code=204, headers=headers)
    return Response(content=data, media_type="image/png", headers=headers)


def _cell_ndvi(
    path: Any, kind: str, bands: dict[str, Any], cells: CellTable, min_valid_share: float
) -> Any:
    """Per-cell NDVI of a plan's cells from one image (both imagery prescriptions use it)."""
    return cell_ndvi(
        path, kind, bands, cells.polygons_utm, cells.epsg, min_valid_share=min_valid_share
    )


@router.post(
    "/imagery/{imagery_id:int}/prescriptions", status_code=201, response_model=PrescriptionOut
)
def prescription_from_imagery(
    imagery_id: int, body: ImageryRxIn, principal: WriterDep, session: SessionDep
) -> dict[str, Any]:
    """Per-cell NDVI (area-weighted mean, share of valid pixels) from an ``ndvi`` or
    ``multispectral`` image into seed 000's NDVI rate model, stored as version 1 of a
    prescription like any other (cells without enough valid pixels get the fallback rate
    and the ``no_data`` flag)."""
    inputs = _rx_inputs(session, principal, imagery_id, body)
    img, plan = inputs[0], inputs[1]
    path = storage.path_for(img.storage_key)
    kind, bands = img.kind, dict(img.bands)

    def ndvi_of(cells: CellTable) -> tuple[np.ndarray, dict[str, Any]]:
        stats = _cell_ndvi(path, kind, bands, cells, body.min_valid_share)
        return stats.mean, {**stats.info, "imagery_id": img.id}

    return _create_rx(
        session,
        principal,
        inputs,
        body,
        ndvi_of,
        body.name or f"NDVI from imagery {img.id} on plan {plan.id}",
        {},
    )


# what an imagery prescription is made from: the image, the plan, its field, the machine
_RxInputs = tuple[Imagery, Plan, FieldRow, Machine | None]


def _rx_inputs(
    session: SessionDep, principal: WriterDep, imagery_id: int, body: ImageryRxIn
) -> _RxInputs:
    img = get_scoped(session, Imagery, imagery_id, principal)
    if img.kind not in ("ndvi", "multispectral"):
        raise ApiError(
            422,
            f"imagery {img.id} is an {img.kind}: NDVI needs an 'ndvi' or 'multispectral' image",
            where="imagery_id",
        )
    plan = session.get(Plan, body.plan_id)
    if plan is None or plan.organisation_id != principal.organisation_id:
        raise ApiError(422, f"plan {body.plan_id} not found", where="plan_id")
    field = session.get(FieldRow, plan.field_id)
    assert field is not None
    machine = None
    if body.machine_id is not None:
        machine = session.get(Machine, body.machine_id)
        if machine is None or machine.organisation_id != principal.organisation_id:
            raise ApiError(422, f"machine {body.machine_id} not found", where="machine_id")
    return img, plan, field, machine


def _create_rx(
    session: SessionDep,
    principal: WriterDep,
    inputs: _RxInputs,
    body: ImageryRxIn,
    cell_source: Any,
    name: str,
    extra_source: dict[str, Any],
) -> dict[str, Any]:
    img, plan, field, machine = inputs
    try:
        meter = rx_meter.meter_spec(
            machine, plan, body.speed_min_kmh, body.speed_max_kmh, body.width_m, body.calibration
        )
        spec = rx_create.NewPrescription(
            name=name,
            product=body.product,
            model="ndvi",
            params=body.params,
            interpolation="imagery",
            interpolation_params={"min_valid_share": body.min_valid_share},
            fallback_rate_kg_ha=body.fallback_rate_kg_ha,
            meter=meter,
            machine_id=body.machine_id,
            cell_source=cell_source,
            source={
                "imagery_id": img.id,
                "kind": img.kind,
                "acquired_on": img.acquired_on.isoformat() if img.acquired_on else None,
                **extra_source,
            },
        )
        rx = rx_create.create_prescription(
            session,
            plan,
            field,
            spec,
            user_id=principal.user_id,
            organisation_id=principal.organisation_id,
        )
    except (ImageryError, ZoneError, *BAD_INPUT) as exc:
        session.rollback()
        raise ApiError(422, str(exc)) from exc
    session.commit()
    return rx_versions.prescription_summary(session, rx)


@router.post("/imagery/{imagery_id:int}/zones", status_code=201, response_model=PrescriptionOut)
def zones_from_imagery(
    imagery_id: int, body: ZonesIn, principal: WriterDep, session: SessionDep
) -> dict[str, Any]:
    """A zone prescription: per-cell NDVI from the image, k-means into ``k`` zones (zone 1
    lowest NDVI), patches under ``min_area_m2`` merged into their main neighbour, and each
    zone's rate from seed 000's NDVI curve at the zone's area-weighted mean NDVI. Stored as
    a versioned prescription (edits, ISOXML treatment zones and Shapefile export as usual);
    the zone table is in ``summary.interpolation.zones``."""
    inputs = _rx_inputs(session, principal, imagery_id, body)
    img, plan = inputs[0], inputs[1]
    path = storage.path_for(img.storage_key)
    kind, bands = img.kind, dict(img.bands)

    def zone_ndvi(cells: CellTable) -> tuple[np.ndarray, dict[str, Any]]:
        stats = _cell_ndvi(path, kind, bands, cells, body.min_valid_share)
        values, zoning = zone_cell_values(
            stats.mean,
            body.k,
            polygons=cells.polygons_utm,
            area_m2=cells.area_m2,
            min_area_m2=body.min_area_m2,
            value_name="ndvi",
        )
        return values, {**stats.info, "imagery_id": img.id, **zoning}

    return _create_rx(
        session,
        principal,
        inputs,
        body,
        zone_ndvi,
        body.name or f"{body.k} NDVI zones from imagery {img.id} on plan {plan.id}",
        {"zones": {"k": body.k, "min_area_m2": body.min_area_m2, "classifier": "kmeans_1d"}},
    )
