"""Shapely geometry -> database geometry (one home for the services and the API layer)."""

from __future__ import annotations

from typing import Any

from geoalchemy2.shape import from_shape
from shapely.geometry.base import BaseGeometry


def shape_to_db(geom: BaseGeometry, srid: int = 4326) -> Any:
    """A shapely geometry as a GeoAlchemy2 WKB element in ``srid`` (default WGS84 lon/lat)."""
    return from_shape(geom, srid=srid)
