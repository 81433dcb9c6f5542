"""Checks an import makes before anything is stored: where its data lies, what exists already.

* Place: a prescription's grid or zones, or a TimeLog's positions, must lie on
  the field they are for. Data that does not touch the field is refused (the
  preview names the geodesic distance, WGS84 ellipsoid); data that covers
  less than ``LOW_OVERLAP_PCT`` of the field is flagged.
* Matching: an imported farm is the organisation's farm of the same name; an
  imported field is an existing field with the same ISOXML partfield id and
  name, or one whose boundary is the same (intersection over union at least
  ``SAME_IOU``), so importing a set twice creates nothing twice.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
from geoalchemy2.shape import to_shape
from pyproj import Geod
from shapely.ops import nearest_points
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from fieldrx.db.geometry import shape_to_db
from fieldrx.db.models import Farm, Field
from fieldrx.geo.crs import to_utm

GEOD = Geod(ellps="WGS84")
LOW_OVERLAP_PCT = 50.0  # a prescription covering less of its field than this is flagged
SAME_IOU = 0.98  # boundaries this alike are the same field (GNSS re-surveys differ by cm)


@dataclass
class Placement:
    """How imported data ``geom`` lies relative to a field (lon/lat geometries)."""

    overlap_pct: float  # share of the field's area the data covers
    distance_m: float  # 0 when they touch

    @property
    def refused(self) -> bool:
        return self.distance_m > 0.0

    def describe(self, what: str, field_name: str) -> str | None:
        if self.refused:
            return (
                f"{what} lies {fmt_distance(self.distance_m)} from field {field_name!r} "
                "and does not overlap it: not imported"
            )
        if self.overlap_pct < LOW_OVERLAP_PCT:
            return f"{what} covers only {self.overlap_pct:.1f} % of field {field_name!r}"
        return None


def fmt_distance(m: float) -> str:
    return f"{m / 1000:,.1f} km" if m >= 1000 else f"{m:,.0f} m"


def geodesic_distance_m(a: Any, b: Any) -> float:
    """Shortest WGS84 ellipsoid distance between two lon/lat geometries (0 if they meet)."""
    if a.intersects(b):
        return 0.0
    pa, pb = nearest_points(a, b)
    return float(GEOD.inv(pa.x, pa.y, pb.x, pb.y)[2])


def placement(field_wgs84: Any, utm_epsg: int, data_wgs84: Any) -> Placement:
    dist = geodesic_distance_m(field_wgs84, data_wgs84)
    if dist > 0:
        return Placement(0.0, dist)
    f = to_utm(field_wgs84, utm_epsg)
    d = to_utm(data_wgs84, utm_epsg)
    share = 100.0 * f.intersection(d).area / max(f.area, 1e-9)
    return Placement(round(share, 2), 0.0)


def points_placement(field_wgs84: Any, lon: np.ndarray, lat: np.ndarray) -> dict[str, Any]:
    """Records on the field and the distance of the nearest one (TimeLog positions)."""
    ok = np.isfinite(lon) & np.isfinite(lat)
    pts = shapely.points(lon[ok], lat[ok])
    if not len(pts):
        return {"on_field": 0, "with_position": 0, "distance_m": None}
    on = int(shapely.intersects(field_wgs84, pts).sum())
    dist = 0.0 if on else geodesic_distance_m(field_wgs84, shapely.multipoints(pts))
    return {"on_field": on, "with_position": len(pts), "distance_m": round(dist, 1)}


def match_farm(session: Session, organisation_id: int, name: str) -> Farm | None:
    return session.scalars(
        select(Farm)
        .where(Farm.organisation_id == organisation_id)
        .where(func.lower(func.btrim(Farm.name)) == name.strip().lower()[:200])
        .order_by(Farm.id)
        .limit(1)
    ).first()


def _iou(a: Any, b: Any, epsg: int) -> float:
    ua, ub = to_utm(a, epsg), to_utm(b, epsg)
    union = ua.union(ub).area
    return float(ua.intersection(ub).area / union) if union > 0 else 0.0


def match_field(
    session: Session, organisation_id: int, ref: str, name: str, geom: Any, epsg: int
) -> tuple[Field | None, str]:
    """An existing field that is this one (see module docstring), and how it was matched."""
    rows = session.scalars(
        select(Field)
        .where(Field.organisation_id == organisation_id)
        .where(func.ST_Intersects(Field.boundary, shape_to_db(geom)))
        .order_by(Field.id)
    ).all()
    for row in rows:
        if ref and row.source_ref == f"ISOXML {ref}" and row.name == name[:200]:
            return row, "ISOXML partfield id and name"
    for row in rows:
        if _iou(to_shape(row.boundary), geom, epsg) >= SAME_IOU:
            return row, "same boundary" + (" and name" if row.name == name[:200] else "")
    return None, ""
