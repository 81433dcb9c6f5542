"""Field boundary validation: a clean MultiPolygon from GeoJSON, or precisely why not.

Checks: type, distinct vertices per ring, coordinate range and
swapped lat/lon order, vertex count, self-intersection with its location,
area between 100 m^2 and 10,000 ha. Area is measured in the field's UTM plane
(``crs.plane_area_m2``, the one area basis), never in degrees. Orientation is
normalised to RFC 7946 (exterior counter-clockwise, holes clockwise).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import shapely
from pyproj import Geod
from shapely.geometry import MultiPolygon, Polygon, shape
from shapely.validation import explain_validity

from fieldrx.geo.crs import epsg_for_geometry, plane_area_m2

MIN_AREA_M2 = 100.0
MAX_AREA_M2 = 10_000.0 * 10_000.0  # 10,000 ha
MAX_VERTICES = 20_000
_GEOD = Geod(ellps="WGS84")


class BoundaryError(ValueError):
    """Invalid boundary. ``where`` is a JSON path, ``location`` a lon/lat point when known."""

    def __init__(
        self, message: str, where: str = "geometry", location: tuple[float, float] | None = None
    ) -> None:
        super().__init__(message)
        self.message = message
        self.where = where
        self.location = location

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"detail": self.message, "where": self.where}
        if self.location is not None:
            out["location"] = list(self.location)
        return out


@dataclass(frozen=True)
class ValidBoundary:
    geometry: MultiPolygon  # WGS84, oriented
    area_m2: float  # in the field's UTM plane (crs.AREA_BASIS)
    utm_epsg: int
    n_vertices: int


def geodesic_area_m2(geom: Polygon | MultiPolygon) -> float:
    """Area on the WGS84 ellipsoid (holes subtracted), whatever way the rings wind.

    ``Geod.geometry_area_perimeter`` sums the rings' *signed* areas, assuming
    RFC 7946 winding (exterior counter-clockwise, holes clockwise): a hole wound
    like its exterior was added instead of subtracted (defect 5). Each
    ring's magnitude is taken on its own instead.
    """
    polys = list(geom.geoms) if isinstance(geom, MultiPolygon) else [geom]
    total = 0.0
    for p in polys:
        total += abs(_GEOD.polygon_area_perimeter(*p.exterior.xy)[0])
        for hole in p.interiors:
            total -= abs(_GEOD.polygon_area_perimeter(*hole.xy)[0])
    return total


def _rings(coords: Any, gtype: str) -> list[tuple[str, Sequence[Any]]]:
    """(json path, ring) for every ring, checking the nesting shape as we go."""
    polys = [coords] if gtype == "Polygon" else coords
    if not isinstance(polys, list | tuple) or not polys:
        raise BoundaryError(f"{gtype} has no coordinates", "geometry.coordinates")
    out: list[tuple[str, Sequence[Any]]] = []
    for pi, poly in enumerate(polys):
        base = "geometry.coordinates" + ("" if gtype == "Polygon" else f"[{pi}]")
        if not isinstance(poly, list | tuple) or not poly:
            raise BoundaryError("polygon has no rings", base)
        for ri, ring in enumerate(poly):
            if not isinstance(ring, list | tuple):
                raise BoundaryError("ring is not a list of positions", f"{base}[{ri}]")
            out.append((f"{base}[{ri}]", ring))
    return out


def _check_positions(rings: list[tuple[str, Sequence[Any]]]) -> int:
    n = 0
    for where, ring in rings:
        for vi, pos in enumerate(ring):
            path = f"{where}[{vi}]"
            if (
                not isinstance(pos, list | tuple)
                or len(pos) < 2
                or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in pos[:2])
            ):
                raise BoundaryError(f"vertex {vi} is not a [lon, lat] pair of numbers", path)
            lon, lat = float(pos[0]), float(pos[1])
            if not (math.isfinite(lon) and math.isfinite(lat)):
                raise BoundaryError(f"vertex {vi} has a non-finite coordinate", path)
            if abs(lat) > 90.0 and abs(lon) <= 90.0:
                raise BoundaryError(
                    f"vertex {vi} ({lon}, {lat}): latitude out of range; the coordinates look "
                    "swapped (GeoJSON order is [longitude, latitude])",
                    path,
                )
            if abs(lon) > 180.0 or abs(lat) > 90.0:
                raise BoundaryError(
                    f"vertex {vi} ({lon}, {lat}) is out of range (lon -180..180, lat -90..90)",
                    path,
                )
        distinct = {(float(p[0]), float(p[1])) for p in ring}
        if len(distinct) < 3:
            raise BoundaryError(
                f"ring has {len(distinct)} distinct vertices; a ring needs at least 3", where
            )
        n += len(ring)
        if n > MAX_VERTICES:
            raise BoundaryError(
                f"boundary has more than {MAX_VERTICES} vertices; simplify it first", where
            )
    return n


def _swapped_hint(geom: Polygon | MultiPolygon) -> bool:
    """Every vertex would also be valid swapped; used only to enrich the area message."""
    minx, miny, maxx, maxy = geom.bounds
    return bool(max(abs(minx), abs(maxx)) <= 90.0)


_LOC = re.compile(r"\[([-0-9.eE+]+) ([-0-9.eE+]+)\]")


def validate_boundary(geometry: Any) -> ValidBoundary:
    """Validate a GeoJSON geometry dict; return the oriented MultiPolygon with area and UTM zone."""
    if not isinstance(geometry, dict):
        raise BoundaryError("geometry must be a GeoJSON object")
    gtype = geometry.get("type")
    if gtype not in ("Polygon", "MultiPolygon"):
        raise BoundaryError(
            f"geometry type {gtype!r} is not a Polygon or MultiPolygon", "geometry.type"
        )
    rings = _rings(geometry.get("coordinates"), gtype)
    n_vertices = _check_positions(rings)
    try:
        geom = shape(geometry)
    except (ValueError, TypeError, shapely.errors.GEOSException) as exc:
        raise BoundaryError(f"cannot build the polygon: {exc}") from exc
    if not geom.is_valid:
        reason = explain_validity(geom)
        m = _LOC.search(reason)
        loc = (float(m.group(1)), float(m.group(2))) if m else None
        what = reason.split("[")[0].strip()
        at = f" at ({loc[0]:.7f}, {loc[1]:.7f})" if loc else ""
        raise BoundaryError(f"invalid boundary: {what}{at}", "geometry.coordinates", loc)
    epsg = epsg_for_geometry(geom)
    area = plane_area_m2(geom, epsg)
    if area < MIN_AREA_M2:
        raise BoundaryError(f"area {area:.1f} m² is below the minimum of {MIN_AREA_M2:.0f} m²")
    if area > MAX_AREA_M2:
        hint = " (are lon/lat swapped?)" if _swapped_hint(geom) else ""
        raise BoundaryError(f"area {area / 10_000:.0f} ha is above the maximum of 10,000 ha{hint}")
    polys = list(geom.geoms) if isinstance(geom, MultiPolygon) else [geom]
    oriented = MultiPolygon([shapely.geometry.polygon.orient(p, sign=1.0) for p in polys])
    return ValidBoundary(
        geometry=oriented,
        area_m2=area,
        utm_epsg=epsg,
        n_vertices=n_vertices,
    )
