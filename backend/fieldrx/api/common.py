"""Helpers shared by the routers: scoped lookups and GeoJSON conversion."""

from __future__ import annotations

from typing import Any, TypeVar

import orjson
from fastapi import HTTPException, status
from fastapi.responses import Response
from geoalchemy2.shape import to_shape
from shapely.geometry import mapping
from shapely.geometry.base import BaseGeometry
from sqlalchemy import Result
from sqlalchemy.orm import Session

from fieldrx.auth.deps import Principal
from fieldrx.errors import DomainError

T = TypeVar("T")


def get_scoped(session: Session, model: type[T], obj_id: int, principal: Principal) -> T:
    """Fetch a row of the caller's organisation; anything else is a 404 (ids do not leak)."""
    obj = session.get(model, obj_id)
    if obj is None or obj.organisation_id != principal.organisation_id:  # type: ignore[attr-defined]
        raise HTTPException(
            status.HTTP_404_NOT_FOUND, f"{model.__name__.lower()} {obj_id} not found"
        )
    return obj


def geom_to_geojson(geom: Any) -> dict[str, Any]:
    """WKB element or shapely geometry -> GeoJSON geometry dict."""
    shp = geom if isinstance(geom, BaseGeometry) else to_shape(geom)
    return mapping(shp)


class ApiError(DomainError):
    """An error a router decides the status of: answered like every domain error, as the one
    error body ``{"detail": message, **extra}`` (``schemas.errors.ErrorOut``).

    Lower layers raise ``fieldrx.errors`` classes instead (they never import this module)."""

    def __init__(self, status_code: int, message: str, **extra: Any) -> None:
        super().__init__(message, **extra)
        self.status = status_code


def point_page(rows: Result[Any], total: int, limit: int, offset: int, **extra: Any) -> Response:
    """A page of telemetry rows (a query result with lon/lat columns) as a GeoJSON
    FeatureCollection.

    Rows are read as tuples and encoded with orjson (datetimes as ISO 8601, as FastAPI's
    encoder writes them): reading 5,000 rows as mappings and FastAPI's generic encoder
    took ~250 ms, several times the query (bench/telemetry_query.py)."""
    keys = list(rows.keys())
    ilon, ilat = keys.index("lon"), keys.index("lat")
    props = [i for i, k in enumerate(keys) if k not in ("lon", "lat")]
    names = [keys[i] for i in props]
    feats = [
        {
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": [r[ilon], r[ilat]]},
            "properties": dict(zip(names, [r[i] for i in props], strict=True)),
        }
        for r in rows
    ]
    nxt = offset + len(feats)
    body = {
        "type": "FeatureCollection",
        "features": feats,
        **extra,
        "total": total,
        "limit": limit,
        "offset": offset,
        "next_offset": nxt if nxt < total else None,
    }
    return Response(orjson.dumps(body), media_type="application/json")
