"""Helpers shared by the routers: scoped lookups and GeoJSON conversion."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any, TypeVar

from fastapi import HTTPException, status
from geoalchemy2.shape import to_shape
from shapely.geometry import mapping
from shapely.geometry.base import BaseGeometry
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


def point_page(
    rows: Iterable[Mapping[str, Any]], total: int, limit: int, offset: int, **extra: Any
) -> dict[str, Any]:
    """A page of telemetry rows (with lon/lat columns) as a GeoJSON FeatureCollection."""
    feats = [
        {
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": [r["lon"], r["lat"]]},
            "properties": {k: v for k, v in r.items() if k not in ("lon", "lat")},
        }
        for r in rows
    ]
    nxt = offset + len(feats)
    return {
        "type": "FeatureCollection",
        "features": feats,
        **extra,
        "total": total,
        "limit": limit,
        "offset": offset,
        "next_offset": nxt if nxt < total else None,
    }
