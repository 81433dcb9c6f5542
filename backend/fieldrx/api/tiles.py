"""Vector tiles (MVT) of plan and prescription grids, layer "cells", scoped to the organisation."""

from __future__ import annotations

import gzip

from fastapi import APIRouter, Request, Response
from geoalchemy2.shape import to_shape

from fieldrx.api.common import ApiError, get_scoped
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.files import MVT, TILE_RESPONSES
from fieldrx.auth.deps import SessionDep, UserDep
from fieldrx.db.models import Field, Plan, Prescription, PrescriptionVersion
from fieldrx.services import tiles

router = APIRouter(prefix="/tiles", tags=["tiles"], responses=ERRORS)

MAX_ZOOM = 24


def _check_xyz(z: int, x: int, y: int) -> None:
    if not 0 <= z <= MAX_ZOOM:
        raise ApiError(422, f"zoom must be 0..{MAX_ZOOM}, got {z}")
    if not (0 <= x < (1 << z) and 0 <= y < (1 << z)):
        raise ApiError(422, f"tile {z}/{x}/{y} does not exist (x and y must be < {1 << z})")


def _lod(session: SessionDep, plan: Plan, z: int) -> tuple[bool, tuple[int, int]]:
    """Level of detail: overview or not, and the sampling strides of an overview."""
    field = session.get(Field, plan.field_id)
    lat = to_shape(field.boundary).centroid.y if field is not None else 0.0
    width = float((plan.params or {}).get("swath_width_m") or 2.3)
    length = float((plan.params or {}).get("cell_length_m") or 5.0)
    overview = tiles.use_overview(z, min(width, length), lat)
    return overview, tiles.strides(z, width, length, lat) if overview else (1, 1)


def _tile_response(request: Request, etag: str, data: bytes) -> Response:
    """Tile bytes with ETag / Cache-Control; gzipped when the client accepts it (MVT
    compresses ~3-4x, and browsers decode Content-Encoding transparently)."""
    headers = {"ETag": etag, "Cache-Control": "private, max-age=86400", "Vary": "Accept-Encoding"}
    if request.headers.get("if-none-match") == etag:
        return Response(status_code=304, headers=headers)
    if len(data) > 512 and "gzip" in request.headers.get("accept-encoding", ""):
        data = gzip.compress(data, compresslevel=5, mtime=0)
        headers["Content-Encoding"] = "gzip"
    return Response(content=data, media_type=MVT, headers=headers)


@router.get(
    "/plans/{plan_id:int}/{z:int}/{x:int}/{y:int}.mvt",
    response_class=Response,
    responses=TILE_RESPONSES,
)
def plan_tile(
    plan_id: int, z: int, x: int, y: int, request: Request, principal: UserDep, session: SessionDep
) -> Response:
    """Cells of a plan (props seq, swath; overview tiles add n_cells)."""
    plan = get_scoped(session, Plan, plan_id, principal)
    _check_xyz(z, x, y)
    overview, stride = _lod(session, plan, z)
    etag = f'"plan-{plan.id}-{int(plan.created_at.timestamp())}-{z}-{x}-{y}"'
    if request.headers.get("if-none-match") == etag:
        return _tile_response(request, etag, b"")
    return _tile_response(
        request, etag, tiles.plan_tile(session, plan.id, z, x, y, overview, stride)
    )


@router.get(
    "/prescriptions/{rx_id:int}/{version:int}/{z:int}/{x:int}/{y:int}.mvt",
    response_class=Response,
    responses=TILE_RESPONSES,
)
def prescription_tile(
    rx_id: int,
    version: int,
    z: int,
    x: int,
    y: int,
    request: Request,
    principal: UserDep,
    session: SessionDep,
) -> Response:
    """Cells of one prescription version (props seq, rate_kg_ha, flags, clamped)."""
    rx = get_scoped(session, Prescription, rx_id, principal)
    _check_xyz(z, x, y)
    ver = (
        session.query(PrescriptionVersion).filter_by(prescription_id=rx.id, version=version).first()
    )
    if ver is None:
        raise ApiError(404, f"prescription {rx_id} has no version {version}")
    plan = session.get(Plan, rx.plan_id)
    assert plan is not None
    etag = f'"rx-{ver.id}-{z}-{x}-{y}"'
    if request.headers.get("if-none-match") == etag:
        return _tile_response(request, etag, b"")
    overview, stride = _lod(session, plan, z)
    data = tiles.prescription_tile(session, plan.id, ver.id, z, x, y, overview, stride)
    return _tile_response(request, etag, data)
