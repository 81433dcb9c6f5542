"""Stage 1: the field boundary the planner works on, and every change made to it.

The planner and the grid accept only a clean Polygon/MultiPolygon in UTM metres.
Repairs (``make_valid`` of a slightly invalid ring) and the simplification of traced
boundaries change the user's field, so each change is returned as a warning that ends
up in the plan metrics (nothing is changed silently).
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

from .. import PlanningError

SNAP_GRID_M = 1e-3  # snap-rounding grid used when GEOS fails on a boundary


def parts(g: BaseGeometry) -> list[Polygon]:
    """Polygonal parts of g with area."""
    return [p for p in shapely.get_parts(g) if isinstance(p, Polygon) and p.area > 0]


def polygonal(geom: BaseGeometry, warnings: list[str] | None = None) -> Polygon | MultiPolygon:
    """The field as a valid, normalised Polygon/MultiPolygon, or PlanningError saying why.

    A slightly invalid ring (a spike, a repeated touch) is repaired with ``make_valid``
    when that changes the area by at most 1 %; the repair is appended to ``warnings``.
    """
    if geom is None or geom.is_empty:
        raise PlanningError("the field boundary is empty")
    if not isinstance(geom, Polygon | MultiPolygon):
        raise PlanningError(f"the field must be a Polygon or MultiPolygon, got {geom.geom_type}")
    if not geom.is_valid:
        reason = shapely.is_valid_reason(geom)
        fixed = shapely.make_valid(geom)
        polys = parts(fixed)
        if not polys:
            raise PlanningError(f"the field boundary is degenerate ({reason})")
        fixed = shapely.union_all(polys)
        if abs(fixed.area - abs(geom.area)) > 0.01 * max(fixed.area, 1e-9):
            raise PlanningError(f"the field boundary is invalid: {reason}")
        if warnings is not None:
            warnings.append(
                f"the boundary was repaired ({reason}); area changed by "
                f"{abs(fixed.area - abs(geom.area)):.2f} m²"
            )
        geom = fixed
    geom = shapely.normalize(geom)
    if geom.area <= 0:
        raise PlanningError("the field has no area (degenerate boundary)")
    return geom


def simplified(
    fld: Polygon | MultiPolygon, tol: float, warnings: list[str] | None = None
) -> Polygon | MultiPolygon:
    """Boundary without detail finer than ``tol`` (digitising / GNSS noise).

    A jagged boundary makes strips split into teeth: many tiny swaths and blocks for
    detail the implement cannot follow anyway. Douglas-Peucker at a quarter of the
    working width (at most 1 m) removes that noise; corners of real fields stay. Only
    dense (traced / GNSS-recorded) boundaries are touched: median edge shorter than
    ``8 * tol``; a drawn polygon keeps its exact vertices. The change is reported.
    """
    if tol <= 0:
        return fld
    lens = np.concatenate(
        [
            np.hypot(*np.diff(np.asarray(r.coords), axis=0).T)
            for p in parts(fld)
            for r in [p.exterior, *p.interiors]
        ]
    )
    if np.median(lens) >= 8 * tol:
        return fld
    simp = fld.simplify(tol, preserve_topology=True)
    if (
        simp.is_empty
        or not simp.is_valid
        or not isinstance(simp, Polygon | MultiPolygon)
        or abs(simp.area - fld.area) > 0.01 * fld.area
    ):
        return fld
    simp = shapely.normalize(simp)
    if warnings is not None:
        warnings.append(
            f"traced boundary simplified at {tol:.2f} m: {shapely.get_num_coordinates(fld)} -> "
            f"{shapely.get_num_coordinates(simp)} vertices, area "
            f"{simp.area - fld.area:+.1f} m²"
        )
    return simp


def snapped(geom: BaseGeometry, grid_m: float = SNAP_GRID_M) -> Polygon | MultiPolygon:
    """The boundary snap-rounded to a ``grid_m`` grid (GEOS's robust overlay input)."""
    out = shapely.set_precision(geom, grid_m)
    ps = parts(out)
    if not ps:
        raise PlanningError("the field boundary collapses when snapped to a 1 mm grid")
    return shapely.union_all(ps)


def min_width(geom: BaseGeometry) -> float:
    """Narrowest width of the convex hull (rotating calipers: one side lies on a hull edge)."""
    hull_geom = geom.convex_hull
    if not isinstance(hull_geom, Polygon) or hull_geom.area <= 0:
        return 0.0
    hull = np.asarray(hull_geom.exterior.coords)
    e = np.diff(hull, axis=0)
    lengths = np.hypot(e[:, 0], e[:, 1])
    e = e[lengths > 0] / lengths[lengths > 0, None]
    normal = np.stack([-e[:, 1], e[:, 0]], axis=1)
    proj = hull @ normal.T
    return float(np.min(proj.max(axis=0) - proj.min(axis=0)))


def max_extent(geom: BaseGeometry) -> float:
    """Largest width of the convex hull over all directions (its diameter)."""
    hull = np.asarray(shapely.get_coordinates(geom.convex_hull))
    if len(hull) < 2:
        return 0.0
    d = hull[:, None, :] - hull[None, :, :]
    return float(np.sqrt((d**2).sum(-1)).max())
