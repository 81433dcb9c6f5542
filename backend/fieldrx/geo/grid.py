"""The path-ordered grid: a cell every L metres along each swath, w wide (seed 001 sec. 1.2).

Seed 001 cuts the planned path at a fixed cell length (L >= v_max * T_lag; 5 m) and gives
each cell four corners numbered counter-clockwise (Table 1), stored in path order so the
terminal can follow the path and drop finished cells. Here the corners of every cell are
listed rear-right, front-right, front-left, rear-left relative to the driving direction,
which is counter-clockwise. ``corners_utm`` is the nominal (unclipped) implement footprint
of the cell; ``polygons_utm`` is the cell clipped to the field (partial cells at the
boundary, slivers merged into their neighbour along the same swath; a cell split by a
notch or hole stays one MultiPolygon). Field area no swath covers is never merged into a
cell; it is reported as ``uncovered_m2``. The result is the one cell type,
:class:`fieldrx.geo.cells.Cells` (``Grid`` is its name here).

The grid reads only the documented strip geometry of each swath
(:class:`fieldrx.geo.planning.model.StripGeometry`) and the plan's frame.

Inner swaths are cut in the planner's rotated frame with numpy; only cells that reach a
boundary (decided exactly from the strip-column intervals the planner computed) are
clipped with shapely, so a 1,000 ha field (~870k cells) takes seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon
from shapely.geometry.base import BaseGeometry

from . import PlanningError
from .cells import Cells, index_in_swath, rectangles
from .coverage import CoveragePlan, Swath
from .planning.boundary import polygonal

MAX_CELLS = 5_000_000
MIN_CELL_LENGTH_M = 0.5


def check_grid_cost(area_m2: float, swath_width_m: float, cell_length_m: float) -> float:
    """The cost estimate every entry point (API, import confirm, batch, CLI) applies before
    any planning: the expected number of cells, or ``PlanningError``.

    Every cell is at most one swath wide and one cell long, so a field of area A needs
    about A / (w L) cells. A cell length under ``MIN_CELL_LENGTH_M`` (or not finite) is
    refused here, before the coverage path is planned: the grid would refuse it anyway,
    but only after planning, which a millimetre swath makes take minutes. A non-finite or
    non-positive swath width is left to the planner's own message.
    """
    w, length = float(swath_width_m), float(cell_length_m)
    if not math.isfinite(length) or length < MIN_CELL_LENGTH_M:
        raise PlanningError(f"cell_length_m must be >= {MIN_CELL_LENGTH_M} m, got {cell_length_m}")
    if not (math.isfinite(w) and w > 0):
        return 0.0
    n_est = float(area_m2) / (w * length)
    if n_est > MAX_CELLS:
        raise PlanningError(
            f"swath width {w:g} m and cell length {length:g} m give about {n_est:,.0f} cells on "
            f"this {area_m2 / 10_000:,.1f} ha field, more than {MAX_CELLS} (the limit): "
            "use a wider swath or longer cells"
        )
    return n_est


# The grid is the one cell type (``geo.cells.Cells``) with the builder's metadata filled in
Grid = Cells


@dataclass
class _Cells:
    swath: np.ndarray
    idx: np.ndarray
    corners: np.ndarray
    polys: np.ndarray
    area: np.ndarray
    headland: bool


def _n_cells(length: float, cell: float) -> int:
    return max(1, math.ceil(length / cell - 1e-9))


def build_grid(
    plan: CoveragePlan,
    boundary_utm: BaseGeometry | None = None,
    cell_length_m: float = 5.0,
    min_cell_fraction: float = 0.1,
    epsg: int = 0,
) -> Cells:
    """Cut the plan's path into cells (see module docstring); ``epsg`` (the field's UTM
    zone, 0 unknown) gives the cells their WGS84 views.

    A GEOS exception while clipping cells becomes a PlanningError that says so; it never
    reaches the user as a TopologyException.
    """
    try:
        return _build_grid(plan, boundary_utm, cell_length_m, min_cell_fraction, epsg)
    except shapely.errors.GEOSException as exc:
        raise PlanningError(
            f"the geometry engine failed while cutting cells ({exc}); try another cell "
            "length or heading, or simplify the boundary"
        ) from exc


def _build_grid(
    plan: CoveragePlan,
    boundary_utm: BaseGeometry | None,
    cell_length_m: float,
    min_cell_fraction: float,
    epsg: int,
) -> Cells:
    import time

    t0 = time.perf_counter()
    cell = float(cell_length_m)
    if not math.isfinite(cell) or cell < MIN_CELL_LENGTH_M:
        raise PlanningError(f"cell_length_m must be >= {MIN_CELL_LENGTH_M} m, got {cell_length_m}")
    if not (0.0 <= min_cell_fraction < 1.0):
        raise PlanningError(f"min_cell_fraction must be in [0, 1), got {min_cell_fraction}")
    if boundary_utm is not None:
        fld = polygonal(boundary_utm)
        ref = plan.input_field if plan.input_field is not None else plan.field
        if abs(fld.symmetric_difference(ref).area) > 1e-6 * ref.area:
            raise PlanningError("boundary_utm is not the field this plan was made for")
    w = plan.swath_width_m
    n_est = sum(_n_cells(s.line.length, cell) for s in plan.swaths)
    if n_est > MAX_CELLS:
        raise PlanningError(
            f"the grid would have {n_est} cells, more than {MAX_CELLS}: use longer cells"
        )
    timings: dict[str, float] = {}
    parts: list[_Cells] = []
    inner = [s for s in plan.swaths if s.kind == "inner"]
    t = time.perf_counter()
    inner_cells = _inner_cells(plan, inner, cell) if inner else None
    timings["inner_cells"] = time.perf_counter() - t
    t = time.perf_counter()
    rings = [s for s in plan.swaths if s.kind == "headland"]
    head = [_ring_cells(s, w, cell) for s in rings]
    head_cells = _resolve_overlaps(head) if head else []
    if head_cells:
        _fill_bands(head_cells, [s.strip for s in rings])
    timings["headland_cells"] = time.perf_counter() - t

    # put the pieces back into path order
    hi = 0
    for s in plan.swaths:
        if s.kind == "headland":
            parts.append(head_cells[hi])
            hi += 1
    if inner_cells is not None:
        parts.append(inner_cells)
    key = np.concatenate([p.swath for p in parts]) * (1 << 32) + np.concatenate(
        [p.idx for p in parts]
    )
    order = None if (np.diff(key) > 0).all() else np.argsort(key, kind="stable")
    cat = {
        k: np.concatenate([getattr(p, k) for p in parts])
        for k in ("swath", "idx", "corners", "polys", "area")
    }
    hl = np.concatenate([np.full(len(p.swath), p.headland) for p in parts])
    if order is not None:
        cat = {k: v[order] for k, v in cat.items()}
        hl = hl[order]
    t = time.perf_counter()
    keep = _merge_slivers(cat, min_cell_fraction * cell * w)
    timings["slivers"] = time.perf_counter() - t
    n = int(keep.sum())
    if n == 0:
        raise PlanningError("the grid is empty (field smaller than one cell)")
    timings["total"] = time.perf_counter() - t0
    field_area = plan.field.area  # the planned (possibly simplified) field
    return Cells(
        epsg=epsg,
        seq=np.arange(n, dtype=np.int64),
        swath=cat["swath"][keep],
        index_in_swath=index_in_swath(cat["swath"][keep]),
        area_m2=cat["area"][keep],
        corners_utm=cat["corners"][keep],
        polygons_utm=cat["polys"][keep],
        headland=hl[keep],
        cell_length_m=cell,
        swath_width_m=w,
        uncovered_m2=float(max(0.0, field_area - cat["area"][keep].sum())),
        timings_s=timings,
    )


def _inner_cells(plan: CoveragePlan, inner: list[Swath], cell: float) -> _Cells:
    w = plan.swath_width_m
    fr = plan.frame
    sidx = np.array([s.index for s in inner], np.int64)
    x0 = np.array([s.strip.x0 for s in inner])
    x1 = np.array([s.strip.x1 for s in inner])
    y = np.array([s.strip.y for s in inner])
    d = np.array([s.direction for s in inner], np.float64)
    k = np.maximum(1, np.ceil((x1 - x0) / cell - 1e-9)).astype(np.int64)
    rep = np.repeat(np.arange(len(inner)), k)
    offs = np.cumsum(k) - k
    j = np.arange(int(k.sum())) - np.repeat(offs, k)
    X0, X1, Y, D = x0[rep], x1[rep], y[rep], d[rep]
    start = np.where(D > 0, X0 + j * cell, X1 - j * cell)
    end = np.where(D > 0, np.minimum(X0 + (j + 1) * cell, X1), np.maximum(X1 - (j + 1) * cell, X0))
    ry = Y - D * w / 2.0
    ly = Y + D * w / 2.0
    cf = np.empty((len(j), 4, 2))
    cf[:, 0, 0], cf[:, 0, 1] = start, ry
    cf[:, 1, 0], cf[:, 1, 1] = end, ry
    cf[:, 2, 0], cf[:, 2, 1] = end, ly
    cf[:, 3, 0], cf[:, 3, 1] = start, ly
    lo = np.minimum(start, end)
    hi = np.maximum(start, end)

    # exact "whole cell inside the region" test from the strip-column intervals
    inside = np.zeros(len(j), bool)
    for m, s in enumerate(inner):
        sl = slice(offs[m], offs[m] + k[m])
        full = s.strip.full
        if full is None or len(full) == 0:
            continue
        q = np.searchsorted(full[:, 0], lo[sl] + 1e-9, side="right") - 1
        ok = q >= 0
        inside[sl] = ok & (hi[sl] <= full[np.maximum(q, 0), 1] + 1e-9)

    corners = fr.inv(cf)
    polys = np.empty(len(j), dtype=object)
    area = (hi - lo) * w
    polys[inside] = rectangles(corners[inside])
    part = np.flatnonzero(~inside)
    if len(part):
        clips = np.array([inner[m].strip.clip for m in rep[part]], dtype=object)
        raw = shapely.polygons(cf[part])
        cut = shapely.intersection(raw, clips)
        cut = shapely.transform(_only_polygons(cut), fr.inv)
        polys[part] = cut
        area[part] = shapely.area(cut)
    return _Cells(sidx[rep], j, corners, polys, area, False)


def _only_polygons(geoms: np.ndarray, min_part_m2: float = 1e-4, snap: bool = True) -> np.ndarray:
    """Keep the polygonal parts of overlay results, without needle slivers.

    Overlays leave lines/points where a cell touches the boundary, and near-collinear
    sliver triangles at acute corners; both are dropped (they carry no area but make
    later overlays numerically fragile).
    """
    # snap-round to a 0.1 micrometre grid: collapses zero-width spikes that make later
    # overlays (and the checks on them) numerically fragile
    geoms = np.asarray(geoms, dtype=object)
    if snap:
        geoms = shapely.set_precision(geoms, 1e-7)
    tid = shapely.get_type_id(geoms)
    odd = np.flatnonzero((tid == 7) | (tid == 6))
    for k in odd:
        polys = [
            g
            for g in shapely.get_parts(geoms[k])
            if shapely.get_type_id(g) == 3 and g.area >= min_part_m2
        ]
        if not polys:
            geoms[k] = Polygon()
        elif len(polys) == 1:
            geoms[k] = polys[0]
        else:
            geoms[k] = shapely.multipolygons(polys)
    return geoms


def _ring_cells(s: Swath, w: float, cell: float) -> _Cells:
    """Cells along a closed headland ring: mitred quads between cut lines, clipped to the band."""
    c = np.asarray(s.line.coords)
    seg = np.diff(c, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    keep = seg_len > 1e-9
    c = np.vstack([c[:-1][keep], c[-1:]])
    seg = np.diff(c, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    t = seg / seg_len[:, None]
    nrm = np.stack([-t[:, 1], t[:, 0]], axis=1)  # left normals
    # mitre vectors at vertices (ring is closed: vertex 0 joins the last and first edge)
    # |m| = 1 / cos(half the turn); capped so acute corners give long but finite spikes
    # on the boundary side (the band clip trims them) and short ones on the inner side
    prev = np.roll(nrm, 1, axis=0)
    bis = prev + nrm
    blen = np.hypot(bis[:, 0], bis[:, 1])
    u = np.where(blen[:, None] > 1e-12, bis / np.maximum(blen, 1e-12)[:, None], prev)
    cos_half = np.clip(np.einsum("ij,ij->i", u, nrm), 1e-6, 1.0)
    mit_r = u * np.minimum(1.0 / cos_half, 12.0)[:, None]
    mit_l = u * np.minimum(1.0 / cos_half, 4.0)[:, None]
    cum = np.r_[0.0, np.cumsum(seg_len)]
    total = cum[-1]
    k = _n_cells(total, cell)
    cuts = np.minimum(np.arange(k + 1) * cell, total)
    cuts[-1] = total
    a = 0.75 * w  # reach beyond the band; the band clip trims it

    nv = len(mit_r)

    def at(sv: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        e = int(np.clip(np.searchsorted(cum, sv, side="right") - 1, 0, len(seg_len) - 1))
        d = sv - cum[e]
        if d <= 1e-9:
            return c[e], mit_r[e], mit_l[e]
        if seg_len[e] - d <= 1e-9:
            return c[e + 1], mit_r[(e + 1) % nv], mit_l[(e + 1) % nv]
        return c[e] + t[e] * d, nrm[e], nrm[e]

    better = _offset_curve_cells(s.line, np.array([at(v)[0] for v in cuts]), w)
    corners = np.empty((k, 4, 2))
    polys = []
    for i in range(k):
        p0, r0, l0 = at(cuts[i])
        p1, r1, l1 = at(cuts[i + 1])
        if better is None:  # fallback: mitred quads between perpendicular cut lines
            inner_v = np.flatnonzero((cum > cuts[i] + 1e-9) & (cum < cuts[i + 1] - 1e-9))
            pts = [p0] + [c[v] for v in inner_v] + [p1]
            rs = [r0] + [mit_r[v % nv] for v in inner_v] + [r1]
            ls = [l0] + [mit_l[v % nv] for v in inner_v] + [l1]
            right = [p - a * n for p, n in zip(pts, rs, strict=True)]
            left = [p + a * n for p, n in zip(pts, ls, strict=True)]
            polys.append(shapely.make_valid(Polygon(right + left[::-1])))
        # nominal corners: a w-wide rectangle on the chunk's chord (CCW by construction)
        chord = p1 - p0
        clen = math.hypot(chord[0], chord[1])
        cn = np.array([-chord[1], chord[0]]) / clen if clen > 1e-9 else nrm[0]
        n0 = n1 = cn
        corners[i] = [p0 - (w / 2) * n0, p1 - (w / 2) * n1, p1 + (w / 2) * n1, p0 + (w / 2) * n0]
    if better is not None:
        polys = better
    cells = _only_polygons(
        shapely.intersection(np.array(polys, dtype=object), s.strip.band), snap=better is None
    )
    return _Cells(
        np.full(k, s.index, np.int64),
        np.arange(k),
        corners,
        cells,
        shapely.area(cells),
        True,
    )


def _curve_params(curve: LineString, pts: np.ndarray) -> np.ndarray | None:
    """Unwrapped positions along a closed curve of the points nearest to pts (None if the
    sequence does not run once around the curve in order)."""
    total = curve.length
    t = shapely.line_locate_point(curve, shapely.points(pts))
    d = np.diff(t)
    d = np.where(d < -0.5 * total, d + total, d)
    d = np.where(d > 0.5 * total, d - total, d)
    out = np.r_[t[0], t[0] + np.cumsum(d)]
    # small backward steps (narrow places): clamp, the cut lines then share a point
    if (np.maximum.accumulate(out) - out).max() > 0.25 * total:
        return None
    out = np.maximum.accumulate(out)
    if abs((out[-1] - out[0]) - total) > 0.02 * total:
        return None
    return out


class _Curve:
    """Closed polyline with cumulative lengths, for fast pieces between two positions."""

    def __init__(self, coords: np.ndarray) -> None:
        self.c = coords
        seg = np.hypot(*np.diff(coords, axis=0).T)
        self.cum = np.r_[0.0, np.cumsum(seg)]
        self.length = float(self.cum[-1])

    def point(self, t: float) -> np.ndarray:
        return np.array(
            [np.interp(t, self.cum, self.c[:, 0]), np.interp(t, self.cum, self.c[:, 1])]
        )

    def piece(self, ta: float, tb: float) -> np.ndarray:
        """Coordinates from position ta to tb (tb may exceed the length: wraps once)."""
        if tb <= self.length + 1e-9:
            tb = min(tb, self.length)
            mid = self.c[(self.cum > ta + 1e-9) & (self.cum < tb - 1e-9)]
            return np.vstack([self.point(ta), mid, self.point(tb)])
        first = self.piece(ta, self.length)
        second = self.piece(0.0, tb - self.length)
        return np.vstack([first, second[1:]])


def _offset_curve_cells(
    ring: LineString, cut_pts: np.ndarray, w: float
) -> list[Any] | None:
    """Cells bounded by the ring's offset curves on both sides (nearest-point mapping).

    Cut lines run from each cut point to its nearest points on the two offset curves, so
    at a concave corner they fan into the corner point instead of crossing, and
    consecutive cells always share their cut line. None when the offset curves are not
    single closed curves (narrow places); the caller then keeps the mitred quads.
    """
    a = 0.55 * w
    ring_poly = Polygon(ring.coords)
    if not ring_poly.is_valid:
        return None
    ccw = ring_poly.exterior.is_ccw
    curves = []
    # right of a CCW ring is outside its polygon; right of a CW (hole) ring is inside
    for dist in (a, -a) if ccw else (-a, a):
        grown = ring_poly.buffer(dist, join_style="mitre", mitre_limit=10.0)
        if not isinstance(grown, Polygon) or grown.is_empty:
            return None
        curves.append(LineString(grown.exterior.coords))
    params = []
    for cv in curves:
        t = _curve_params(cv, cut_pts)
        if t is None:
            cv = LineString(np.asarray(cv.coords)[::-1])
            t = _curve_params(cv, cut_pts)
        if t is None:
            return None
        params.append((cv, t))
    (rc_, tr), (lc_, tl) = params
    rc, lc = _Curve(np.asarray(rc_.coords)), _Curve(np.asarray(lc_.coords))
    polys = []
    for i in range(len(cut_pts) - 1):
        right = rc.piece(tr[i] % rc.length, tr[i] % rc.length + tr[i + 1] - tr[i])
        left = lc.piece(tl[i] % lc.length, tl[i] % lc.length + tl[i + 1] - tl[i])
        ring_pts = np.vstack([right, left[::-1]])
        if len(np.unique(np.round(ring_pts, 9), axis=0)) < 3:
            return None
        poly = Polygon(ring_pts)
        polys.append(poly if poly.is_valid else shapely.make_valid(poly))
    return polys


def _resolve_overlaps(rings: list[_Cells]) -> list[_Cells]:
    """Earlier cells (path order) win where headland quads overlap at sharp corners."""
    allp = np.concatenate([r.polys for r in rings])
    tree = shapely.STRtree(allp)
    a_idx, b_idx = tree.query(allp, predicate="intersects")
    pairs = a_idx > b_idx  # later cell a overlaps earlier cell b
    a_idx, b_idx = a_idx[pairs], b_idx[pairs]
    if len(a_idx):
        ov = shapely.area(shapely.intersection(allp[a_idx], allp[b_idx]))
        sel = ov > 1e-9
        for a in np.unique(a_idx[sel]):
            earlier = b_idx[sel & (a_idx == a)]
            allp[a] = _only_polygons(
                np.array([shapely.difference(allp[a], shapely.union_all(allp[earlier]))])
            )[0]
    area = shapely.area(allp)
    out = []
    o = 0
    for r in rings:
        n = len(r.polys)
        out.append(_Cells(r.swath, r.idx, r.corners, allp[o : o + n], area[o : o + n], True))
        o += n
    return out


def _fill_bands(rings: list[_Cells], strips: list[Any]) -> None:
    """Give each pass's band area that none of its rings' cells hold to the adjacent cell.

    The cut-line quads follow a ring's offset curves; where a ring is narrower than its
    offsets (a small sharp loop of a headland-only plan, 13 m long for an 8 m implement)
    they miss part of the band the pass sweeps. That area is worked, so it belongs to a
    cell: each missing piece joins the cell of the same pass sharing most of its
    boundary (the nearest when none touches). Bands are grouped by pass number
    (``StripGeometry.ring_pass``), the documented strip geometry.
    """
    by_pass: dict[int, list[int]] = {}
    for i, st in enumerate(strips):
        by_pass.setdefault(st.ring_pass, []).append(i)
    for members in by_pass.values():
        band = strips[members[0]].band
        if band is None or band.is_empty:
            continue
        polys = np.concatenate([rings[i].polys for i in members])
        owner = np.concatenate([np.full(len(rings[i].polys), i) for i in members])
        local = np.concatenate([np.arange(len(rings[i].polys)) for i in members])
        rest = band.difference(shapely.union_all(polys))
        for piece in shapely.get_parts(rest):
            if piece.area <= 1e-6:
                continue
            shared = shapely.length(shapely.intersection(polys, piece.buffer(1e-6)))
            k = (
                int(np.argmax(shared))
                if shared.max() > 1e-6
                else int(np.argmin(shapely.distance(polys, piece)))
            )
            merged = _only_polygons(np.array([shapely.union(polys[k], piece)]))[0]
            polys[k] = merged
            r = rings[owner[k]]
            r.polys[local[k]] = merged
            r.area[local[k]] = shapely.area(merged)


def _merge_slivers(cat: dict[str, np.ndarray], min_area: float) -> np.ndarray:
    """Merge cells smaller than min_area into their neighbour along the same swath."""
    area = cat["area"]
    keep = area > 1e-9
    small = np.flatnonzero(keep & (area < min_area))
    sw = cat["swath"]
    n = len(area)
    for i in small:
        if not keep[i] or area[i] >= min_area:
            continue
        target = -1
        for step in (-1, 1):
            jj = i + step
            while 0 <= jj < n and sw[jj] == sw[i] and not keep[jj]:
                jj += step
            if 0 <= jj < n and sw[jj] == sw[i] and keep[jj]:
                target = int(jj)
                break
        if target < 0:
            continue  # a swath that is one small cell: kept, its area still needs a rate
        keep[i] = False
        merged = _only_polygons(np.array([shapely.union(cat["polys"][target], cat["polys"][i])]))[0]
        cat["polys"][target] = merged
        cat["area"][target] = shapely.area(merged)
        cr = cat["corners"]
        if target < i:  # the sliver extends the target forward
            cr[target, 1], cr[target, 2] = cr[i, 1], cr[i, 2]
        else:
            cr[target, 0], cr[target, 3] = cr[i, 0], cr[i, 3]
    return keep
