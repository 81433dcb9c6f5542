"""Stage: headland passes (rings around the boundary and the holes) and the inner region.

Pass ``k`` runs on the offset ``(k + 1/2) w`` inside the boundary (and outside every
hole); its band is what its cells are clipped to. The inner region the swaths cover is
the field shrunk by ``h w`` (mitre joins; a subset of the exact erosion, so anything
within ``h w`` of the region stays inside the field).
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import LineString, MultiPolygon, Point, Polygon
from shapely.geometry.base import BaseGeometry
from shapely.geometry.polygon import orient
from shapely.ops import substring

from .. import PlanningError
from .boundary import max_extent, min_width, parts


def headland_rings(
    field_geom: Polygon | MultiPolygon, w: float, h: int
) -> list[tuple[int, LineString, BaseGeometry]]:
    """Rings (pass k, centre line, band) of the h headland passes around boundary and holes."""
    out = []
    for k in range(h):
        centre = field_geom.buffer(-(k + 0.5) * w, join_style="mitre", mitre_limit=5.0)
        outer = field_geom.buffer(-k * w, join_style="mitre", mitre_limit=5.0) if k else field_geom
        inner = field_geom.buffer(-(k + 1) * w, join_style="mitre", mitre_limit=5.0)
        band = outer.difference(inner)
        for poly in parts(centre):
            poly = orient(poly, 1.0)
            for ring in [poly.exterior, *poly.interiors]:
                if ring.length > w:
                    out.append((k, LineString(ring.coords), band))
    return out


def rotate_ring(ring: LineString, pt: np.ndarray, lead: float = 0.0) -> LineString:
    """Closed ring re-started ``lead`` metres after the ring point nearest to pt.

    The lead (2 turning radii) gives the machine room to swing over from the previous
    ring with an S-curve instead of a loop.
    """
    d = (ring.project(Point(pt)) + lead) % ring.length if lead < ring.length else 0.0
    if d <= 1e-9 or d >= ring.length - 1e-9:
        return ring
    a = substring(ring, d, ring.length)
    b = substring(ring, 0.0, d)
    return LineString(np.concatenate([np.asarray(a.coords), np.asarray(b.coords)[1:]]))


def inner_region(
    fld: Polygon | MultiPolygon, w: float, h: int, warnings: list[str]
) -> tuple[BaseGeometry, int]:
    """The area left for inner swaths inside ``h`` headland passes, and the passes used.

    Narrow fields get a plan instead of an error (issue 16): a field narrower than the
    implement is covered by one pass; passes that leave no inner area give a
    headland-only plan; a field too narrow for even one headland ring gets one pass.
    Each adjustment is a warning in the plan.
    """
    extent = max_extent(fld)
    if w > extent:
        raise PlanningError(
            f"swath width {w} m is wider than the field in every direction "
            f"(longest extent {extent:.2f} m): nothing to plan"
        )
    narrow = min_width(fld)
    if narrow < w:
        warnings.append(
            f"the field is narrower than the implement ({narrow:.2f} m < {w} m): one pass"
        )
    if not h:
        return fld, 0
    region = fld.buffer(-h * w, join_style="mitre", mitre_limit=5.0)
    if not region.is_empty and region.area >= 1e-6:
        return shapely.union_all(parts(region)), h
    if headland_rings(fld, w, h):
        warnings.append(
            f"{h} headland passes of {w} m leave no inner area in this field: headland-only plan"
        )
        return Polygon(), h
    warnings.append(
        f"the field is too narrow for a headland pass of {w} m: planned without headland"
    )
    return fld, 0
