"""Stage: plan metrics -- coverage, overlap, outside area, route checks, turn warnings."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import shapely
from shapely.geometry import Polygon

from .boundary import parts
from .kinematics import Machine
from .model import CoveragePlan


def turn_warnings(turns: Any, m: Machine, w: float, h: int, warnings: list[str]) -> None:
    """Tell the user when the turns do not fit the headland or could not be driven."""
    need = turns.required_headland_m
    if need > h * w + 1e-6:
        k = math.ceil(need / w - 1e-9)
        where = "outside the field" if h == 0 else "beyond the headland"
        warnings.append(
            f"turns with a {m.turn_radius_m:g} m radius reach {need:.1f} m {where}: "
            f"{k} headland passes of {w:g} m hold them (the plan has {h})"
        )
    if turns.undrivable:
        warnings.append(
            f"{turns.undrivable} connections could not be made drivable with a "
            f"{m.turn_radius_m:g} m radius inside the field; they follow the shortest "
            "path with sharp corners"
        )


def swath_footprints(plan: CoveragePlan) -> np.ndarray:
    """Area each swath's implement sweeps (w wide), UTM, as a shapely array."""
    w = plan.swath_width_m
    out = []
    inner = [s.strip for s in plan.swaths if s.kind == "inner"]
    if inner:
        c = np.array(
            [
                [[s.x0, s.y - w / 2], [s.x1, s.y - w / 2], [s.x1, s.y + w / 2], [s.x0, s.y + w / 2]]
                for s in inner
            ]
        )
        out.append(shapely.polygons(plan.frame.inv(c)))
    for s in plan.swaths:
        if s.kind == "headland":
            out.append(
                np.array(
                    [s.line.buffer(w / 2, cap_style="flat", join_style="mitre", mitre_limit=5.0)]
                )
            )
    return np.concatenate(out) if out else np.zeros(0, dtype=object)


def fill_metrics(plan: CoveragePlan) -> None:
    fld = plan.field
    area = fld.area
    fp = swath_footprints(plan)
    union = shapely.union_all(fp)
    shapely.prepare(fld)
    inside = shapely.intersection(union, fld).area
    plan.n_swaths = len(plan.swaths)
    plan.n_turns = len(plan.connections)
    plan.working_length_m = float(sum(s.line.length for s in plan.swaths))
    plan.nonworking_length_m = float(sum(c.length for c in plan.connections))
    plan.coverage_pct = 100.0 * inside / area
    # the corner gaps hold no cell even where an inner swath sweeps across them: counted
    # as uncovered (the unswept part already is), so the corners are a part of it
    gaps = plan.corner_gaps
    swept_gaps = 0.0 if gaps is None or gaps.is_empty else shapely.intersection(gaps, union).area
    plan.uncovered_m2 = float(max(0.0, area - inside) + swept_gaps)
    clipped = shapely.area(shapely.intersection(fp, fld)).sum()
    plan.overlap_pct = float(100.0 * max(0.0, clipped - inside) / area)
    plan.outside_pct = 100.0 * max(0.0, union.area - inside) / area
    # per piece (swaths and connections), overlays only for pieces not inside the field:
    # one overlay of the whole route (100k+ turn vertices on 1,000 ha) cost seconds
    pieces = np.array([s.line for s in plan.swaths] + list(plan.connections), dtype=object)
    out = ~shapely.covers(fld, pieces)
    plan.route_outside_m = float(shapely.length(shapely.difference(pieces[out], fld)).sum())
    holes = [Polygon(r) for p in parts(fld) for r in p.interiors]
    plan.route_in_holes_m = 0.0
    for hp in holes:
        hit = shapely.intersects(hp, pieces)
        plan.route_in_holes_m += float(shapely.length(shapely.intersection(pieces[hit], hp)).sum())
