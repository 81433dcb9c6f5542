"""Stage: the driving direction -- candidates, lower bounds, objectives, the search.

``longest_edge`` is seed 001's base line; ``optimal`` minimises an :class:`Objective`
(default :class:`SwathCountObjective`) over the geometry's own directions and every
whole degree with a branch and bound (see :func:`optimal_phi`).
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

from .boundary import parts
from .decomposition import layout
from .frame import frame_for
from .order import endpoints
from .swaths import N_EPS, StripPiece, default_strip_tolerance, holes_of, n_strips

_FIRST_LOOK = 6  # angles with the lowest strip-count bound tried before all the others


def edge_angles(geom: BaseGeometry, max_ring_edges: int = 64) -> np.ndarray:
    """Candidate directions (math angle mod pi): every convex-hull edge (one of them is
    the rotating-calipers minimum-width direction) and the longest ring edges of geom
    (long edges are where swaths parallel to the boundary save turns)."""
    angs, lens = [], []
    for g in parts(geom):
        for ring in [g.exterior, *g.interiors]:
            e = np.diff(np.asarray(ring.coords), axis=0)
            angs.append(np.arctan2(e[:, 1], e[:, 0]) % math.pi)
            lens.append(np.hypot(e[:, 0], e[:, 1]))
    a = np.concatenate(angs) if angs else np.zeros(0)
    ln = np.concatenate(lens) if lens else np.zeros(0)
    a = a[np.argsort(-ln)][:max_ring_edges][ln[np.argsort(-ln)][:max_ring_edges] > 1e-6]
    hull = geom.convex_hull
    if isinstance(hull, Polygon) and not hull.is_empty:
        e = np.diff(np.asarray(hull.exterior.coords), axis=0)
        keep = np.hypot(e[:, 0], e[:, 1]) > 1e-6
        a = np.concatenate([a, np.arctan2(e[keep, 1], e[keep, 0]) % math.pi])
    return np.unique(np.round(a, 9) % math.pi)


def longest_edge_phi(field_geom: Polygon | MultiPolygon) -> float:
    """Seed 001 sec. 1.2: base line = longest edge of the (largest part's) outer boundary."""
    big = max(parts(field_geom), key=lambda p: p.area)
    c = np.asarray(big.exterior.coords)
    e = np.diff(c, axis=0)
    k = int(np.argmax(np.hypot(e[:, 0], e[:, 1])))
    return float(math.atan2(e[k, 1], e[k, 0]) % math.pi)


def crossing_lower_bounds(
    parts: list[Polygon], w: float, phis: np.ndarray, tol: float = 0.0
) -> np.ndarray:
    """Swath-count lower bound per angle, from scan-line crossings (pure numpy).

    Every strip of a part holds at least one swath, and at least one per interval its
    centre line cuts out of the part (the planner splits a strip piece wherever its centre
    line leaves the region), except intervals closer than w/2, which the planner may
    bridge and which count once here; so the sum over strips is <= the swath count.
    """
    lb = np.zeros(len(phis), dtype=np.int64)
    for p in parts:
        c0 = np.asarray(p.centroid.coords[0])
        ext = np.asarray(p.exterior.coords) - c0
        rings = [ext] + [np.asarray(r.coords) - c0 for r in p.interiors]
        a = np.concatenate([r[:-1] for r in rings])
        b = np.concatenate([r[1:] for r in rings])
        for k, phi in enumerate(phis):
            sn, cs = math.sin(phi), math.cos(phi)
            ya = -a[:, 0] * sn + a[:, 1] * cs
            yb = -b[:, 0] * sn + b[:, 1] * cs
            ye = -ext[:, 0] * sn + ext[:, 1] * cs
            y0 = ye.min()
            n = n_strips(ye.max() - y0, w, tol)
            ys = y0 + (np.arange(n) + 0.5) * w
            lo = np.searchsorted(ys, np.minimum(ya, yb), side="left")
            hi = np.searchsorted(ys, np.maximum(ya, yb), side="left")
            cnt = hi - lo
            e = np.repeat(np.arange(len(a)), cnt)
            line = np.repeat(lo, cnt) + (
                np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
            )
            xa = a[e, 0] * cs + a[e, 1] * sn
            xb = b[e, 0] * cs + b[e, 1] * sn
            t = (ys[line] - ya[e]) / (yb[e] - ya[e])
            x = xa + t * (xb - xa)
            order = np.lexsort((x, line))
            line, x = line[order], x[order]
            # crossings pair up into intervals; intervals closer than w/2 count once
            # (the planner bridges such notches), so this stays a lower bound
            starts = np.r_[0, np.flatnonzero(np.diff(line)) + 1]
            pos = np.arange(len(line)) - np.repeat(starts, np.diff(np.r_[starts, len(line)]))
            n_int = np.bincount(line, minlength=n) // 2
            gap_start = (pos % 2 == 1) & (
                pos + 1
                < np.repeat(np.diff(np.r_[starts, len(line)]), np.diff(np.r_[starts, len(line)]))
            )
            gi = np.flatnonzero(gap_start)
            small = (x[gi + 1] - x[gi]) < 0.5 * w
            n_int = n_int - np.bincount(line[gi[small]], minlength=n)
            lb[k] += int(np.maximum(1, n_int).sum())
    return lb


def extent_lower_bounds(parts: list[Polygon], w: float, phis: np.ndarray, tol: float) -> np.ndarray:
    """Swath-count lower bound for many angles at once: every strip of a part holds at
    least one swath, so sum over parts of ``n_strips(width across phi)`` (one matrix
    product over the hull vertices; ~100x cheaper than one layout)."""
    lb = np.zeros(len(phis), dtype=np.int64)
    nrm = np.stack([-np.sin(phis), np.cos(phis)])
    for p in parts:
        hull = np.asarray(p.convex_hull.exterior.coords)
        y = hull @ nrm
        ext = y.max(axis=0) - y.min(axis=0)
        lb += np.maximum(1, np.ceil((ext - tol) / w - N_EPS)).astype(np.int64)
    return lb


def estimate_nonworking(subs: list[StripPiece], blocks: list[list[int]]) -> float:
    """Euclidean turn lengths inside blocks + greedy block-to-block hops (heading tie-break)."""
    total = 0.0
    ends = []
    for b in blocks:
        for j in range(len(b) - 1):
            s, t = subs[b[j]], subs[b[j + 1]]
            x_s, x_t = (s.x1, t.x1) if j % 2 == 0 else (s.x0, t.x0)
            total += math.hypot(x_s - x_t, t.y - s.y)
        ends.append(endpoints(subs, b, 1))
    if len(ends) > 1:
        left = set(range(1, len(ends)))
        cur = ends[0][1]
        while left:
            k = min(left, key=lambda k: math.dist(cur, ends[k][0]))
            total += math.dist(cur, ends[k][0])
            cur = ends[k][1]
            left.remove(k)
    return total


def evaluate(
    region: BaseGeometry,
    w: float,
    phi: float,
    field_geom: BaseGeometry | None = None,
    tol: float | None = None,
) -> tuple[int, float]:
    tol = default_strip_tolerance(w) if tol is None else tol
    fr = frame_for(region, phi)
    parts_rot = [fr.fwd_geom(p) for p in parts(region)]
    holes = fr.fwd_geom(holes_of(field_geom if field_geom is not None else region))
    subs, blocks = layout(parts_rot, w, with_full=False, holes_rot=holes, tol=tol)
    return len(subs), estimate_nonworking(subs, blocks)


def swath_count(
    region: Polygon | MultiPolygon,
    swath_width_m: float,
    phi: float,
    field_geom: BaseGeometry | None = None,
    tol: float | None = None,
) -> int:
    """Number of inner swaths FieldRx generates for region at math angle phi (the objective).

    ``tol`` is the strip tolerance (default :func:`default_strip_tolerance`).
    """
    return evaluate(region, swath_width_m, phi, field_geom, tol)[0]


def heading_objective(
    region: BaseGeometry,
    w: float,
    phi: float,
    field_geom: BaseGeometry | None = None,
    tol: float | None = None,
) -> tuple[int, float]:
    """The objective ``optimal`` minimises at math angle phi, lexicographically: the
    number of inner swaths (each costs a turn), then the estimated non-working distance."""
    n, nonwork = evaluate(region, w, phi, field_geom, tol)
    return n, round(nonwork, 6)


class Objective(Protocol):
    """A heading objective: a value to minimise, lexicographically, whose first element
    is the inner swath count (the branch and bound of :func:`optimal_phi` prunes with
    swath-count lower bounds)."""

    def __call__(
        self,
        region: BaseGeometry,
        w: float,
        phi: float,
        field_geom: BaseGeometry | None,
        tol: float | None,
    ) -> tuple[int, float]: ...


class SwathCountObjective:
    """Fewest swaths (each one costs a turn), then least estimated non-working distance."""

    def __call__(
        self,
        region: BaseGeometry,
        w: float,
        phi: float,
        field_geom: BaseGeometry | None = None,
        tol: float | None = None,
    ) -> tuple[int, float]:
        return heading_objective(region, w, phi, field_geom, tol)


def optimal_phi(
    region: Polygon | MultiPolygon,
    field_geom: Polygon | MultiPolygon,
    w: float,
    check_integer_degrees: bool = True,
    tol: float | None = None,
    objective: Objective | None = None,
) -> tuple[float, dict[str, int]]:
    """Heading that minimises :func:`heading_objective` (swaths, then non-working distance).

    Candidates are the geometry's own directions (every edge of the region and of its
    convex hull -- the rotating-calipers minimum-width direction is one of them -- and
    the field's longest edge) and, with ``check_integer_degrees``, every whole degree,
    which guarantees never needing more swaths than a 1-degree brute-force scan
    (Fields2Cover's BruteForce with the swath-count objective).

    Branch and bound (issue 16): all candidates get the strip-count lower bound
    (:func:`extent_lower_bounds`, one matrix product). The longest edge is evaluated
    first; then the few angles with the lowest bound, then every angle whose bound is
    still below the best count, each pruned by the finer scan-line-crossing bound
    (:func:`crossing_lower_bounds`) before a layout is paid for. An angle whose bound
    equals the best count is not evaluated: ties with the longest edge keep the longest
    edge, so ``optimal`` is never worse than ``longest_edge`` by this objective, but ties
    between other angles are not searched for a lower non-working estimate. On fields
    where the crossing bound is loose (very concave, many spikes) many angles still need
    a layout; bench/planning.py prints the speed-up per field.
    """
    tol = default_strip_tolerance(w) if tol is None else tol
    objective = objective if objective is not None else SwathCountObjective()
    polys = parts(region)
    le = longest_edge_phi(field_geom)
    geo = edge_angles(region)
    geo = np.r_[le, geo[np.abs((geo - le + math.pi / 2) % math.pi - math.pi / 2) > 1e-9]]
    ints = np.radians(np.arange(180.0)) if check_integer_degrees else np.zeros(0)
    near = np.abs((ints[:, None] - geo[None, :] + math.pi / 2) % math.pi - math.pi / 2)
    ints = ints[(near > 1e-9).all(axis=1)] if len(geo) else ints
    angles = np.r_[geo, ints]
    lb = extent_lower_bounds(polys, w, angles, tol)
    results = {le: objective(region, w, le, field_geom, tol)}
    best_n = results[le][0]
    # only angles whose strip-count bound is below the best count can beat it. First the
    # few with the lowest strip-count bound (on most fields one of them is the best), so
    # that the finer crossing bound is then needed for few angles; each angle gets a
    # layout only while its crossing bound is below the best count.
    refined = 0
    done = {0}
    for phase in (np.argsort(lb[1:], kind="stable")[:_FIRST_LOOK] + 1, None):
        open_ = np.flatnonzero(lb < best_n) if phase is None else phase[lb[phase] < best_n]
        open_ = np.array([k for k in open_ if k not in done], int)
        if not len(open_):
            continue
        done.update(open_.tolist())
        lbc = crossing_lower_bounds(polys, w, angles[open_], tol)
        refined += len(open_)
        for j in np.lexsort((angles[open_], lbc)):
            if lbc[j] >= best_n:
                break
            phi = float(angles[open_[j]])
            results[phi] = objective(region, w, phi, field_geom, tol)
            best_n = min(best_n, results[phi][0])
    best = min(results.items(), key=lambda kv: (kv[1][0], kv[1][1], kv[0] != le, kv[0]))
    return best[0], {
        "evaluated": len(results),
        "refined": refined,
        "integer_degree_checks": sum(1 for phi in results if phi in set(ints.tolist())),
        "candidates": len(geo),
    }
