"""Stage: the driving direction -- candidates, lower bounds, objectives, the search.

``longest_edge`` is seed 001's base line; ``optimal`` minimises an :class:`Objective`
(default :class:`SwathCountObjective`) over the geometry's own directions and every
whole degree with a branch and bound (see :func:`optimal_phi`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

import numpy as np
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

from .boundary import parts
from .bounds import AnalyticBounds
from .centrelines import CentreLineCutter, CentreLines, nonworking_estimate
from .decomposition import layout
from .frame import frame_for
from .swaths import default_strip_tolerance, holes_of


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
    top = np.argsort(-ln)[:max_ring_edges]
    a = a[top[ln[top] > 1e-6]]
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


def evaluate(
    region: BaseGeometry,
    w: float,
    phi: float,
    field_geom: BaseGeometry | None = None,
    tol: float | None = None,
) -> int:
    """Number of inner swaths of the swath layout of region at math angle phi."""
    tol = default_strip_tolerance(w) if tol is None else tol
    fr = frame_for(region, phi)
    parts_rot = [fr.fwd_geom(p) for p in parts(region)]
    holes = fr.fwd_geom(holes_of(field_geom if field_geom is not None else region))
    subs, _ = layout(parts_rot, w, with_full=False, holes_rot=holes, tol=tol)
    return len(subs)


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
    return evaluate(region, swath_width_m, phi, field_geom, tol)


def region_lines(region: BaseGeometry, w: float, phi: float, tol: float) -> CentreLines:
    """The centre-line layout of region at phi, in the planning frame's rotation (about
    the region's centroid, :func:`.frame.frame_for`)."""
    return _cutter(region, w, tol)(phi)


def _cutter(region: BaseGeometry, w: float, tol: float) -> CentreLineCutter:
    """The centre-line cutter of region's parts in the planning frame (about its centroid)."""
    c = region.centroid
    return CentreLineCutter(parts(region), w, tol, np.array([c.x, c.y]))


def heading_objective(
    region: BaseGeometry,
    w: float,
    phi: float,
    field_geom: BaseGeometry | None = None,
    tol: float | None = None,
) -> tuple[int, float]:
    """The objective ``optimal`` minimises at math angle phi, lexicographically: the
    number of inner swaths of the swath layout (each costs a turn), then the estimated
    non-working distance of the centre-line layout (:func:`.centrelines.nonworking_estimate`:
    turns and block-to-block hops, from the vertices alone)."""
    tol = default_strip_tolerance(w) if tol is None else tol
    n = evaluate(region, w, phi, field_geom, tol)
    return n, round(float(nonworking_estimate(region_lines(region, w, phi, tol))), 6)


class Objective(Protocol):
    """A heading objective: a value to minimise, lexicographically, whose first element
    is the inner swath count (the branch and bound of :func:`optimal_phi` prunes with
    swath-count lower bounds) and whose second is a function of the centre-line layout
    alone (``secondary``: the search ranks angles of equal count bounds by it before it
    pays for a swath layout). The search assembles the value from these two parts (the
    count of :func:`evaluate`, ``secondary`` of the lines it has already cut), so
    ``__call__`` is the value for callers that hold no centre lines (a brute-force scan,
    the tests)."""

    def __call__(
        self,
        region: BaseGeometry,
        w: float,
        phi: float,
        field_geom: BaseGeometry | None,
        tol: float | None,
    ) -> tuple[int, float]: ...

    def secondary(self, lines: CentreLines) -> float:
        """The second element of ``__call__`` at the angle of ``lines`` (exactly)."""
        ...


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

    def secondary(self, lines: CentreLines) -> float:
        return round(float(nonworking_estimate(lines)), 6)


def _candidates(
    region: BaseGeometry, field_geom: BaseGeometry, check_integer_degrees: bool
) -> tuple[np.ndarray, np.ndarray]:
    """(all candidate angles, longest edge first; the whole degrees among them)."""
    le = longest_edge_phi(field_geom)
    geo = edge_angles(region)
    geo = np.r_[le, geo[np.abs((geo - le + math.pi / 2) % math.pi - math.pi / 2) > 1e-9]]
    if not check_integer_degrees:
        return geo, np.zeros(0)
    ints = np.radians(np.arange(180.0))
    k = np.rint(np.degrees(geo)).astype(np.int64) % 180  # the one whole degree near each
    near = np.abs((ints[k] - geo + math.pi / 2) % math.pi - math.pi / 2) <= 1e-9
    keep = np.ones(180, bool)
    keep[k[near]] = False
    return np.concatenate([geo, ints[keep]]), ints[keep]


def optimal_phi(
    region: Polygon | MultiPolygon,
    field_geom: Polygon | MultiPolygon,
    w: float,
    check_integer_degrees: bool = True,
    tol: float | None = None,
    objective: Objective | None = None,
) -> tuple[float, dict[str, int]]:
    """Heading that minimises the objective (swaths, then non-working distance).

    Candidates are the geometry's own directions (every edge of the region and of its
    convex hull -- the rotating-calipers minimum-width direction is one of them -- and
    the field's longest edge) and, with ``check_integer_degrees``, every whole degree,
    which guarantees never needing more swaths than a 1-degree brute-force scan
    (Fields2Cover's BruteForce with the swath-count objective).

    Branch and bound on the lexicographic key (swath-count lower bound,
    second criterion), which is a lower bound on the objective at every candidate: every
    candidate gets the analytic swath-count lower bound (:class:`.bounds.AnalyticBounds`,
    all angles in one vectorised pass over the vertices, no swath generation), first
    without its dearest term (the isolation test of the spike tips), which is added
    only for the angles the search may still take. The candidate of least key is then,
    in turn: tightened (full analytic bound), probed (its centre-line layout,
    :mod:`.centrelines`: the scan-line count bound and the exact second criterion, a few
    per cent of a layout), and only then evaluated (one swath layout: the count; the
    second criterion is the probe's). The search stops when the least key is not below
    the best value found. The count bound equals the true count at the optimum on the
    bench fields, so one layout usually decides, ties in the count included: they are
    ranked by the exact second criterion before any layout (with the layout-based
    estimate, each tied whole degree cost a layout: 2-3 on four bench fields at 12 m).
    What is left is the bounds' and probes' own cost, numpy's per-call overhead mostly
    (about 2 ms on the irregular 40-vertex field at 12 m beside a 3.2 ms layout, 0.9 ms
    beside 0.8 ms on the L at 12 m; ``bench/planning.py`` prints the speed-ups).
    The longest edge is first among equal keys and wins exact ties, so ``optimal`` is
    never worse than ``longest_edge`` by the objective.
    """
    tol = default_strip_tolerance(w) if tol is None else tol
    objective = objective if objective is not None else SwathCountObjective()
    polys = parts(region)
    angles, ints = _candidates(region, field_geom, check_integer_degrees)
    le = float(angles[0])
    bounds = AnalyticBounds(polys, w, angles, tol, holes_of(field_geom))
    results, probed = _branch_and_bound(
        bounds,
        _cutter(region, w, tol),
        objective.secondary,
        lambda phi: evaluate(region, w, phi, field_geom, tol),
    )
    best = min(results.items(), key=lambda kv: (kv[1][0], kv[1][1], kv[0] != le))
    ints_set = set(ints.tolist())
    return best[0], {
        "evaluated": len(results),
        "refined": probed,
        "integer_degree_checks": sum(1 for phi in results if phi in ints_set),
        "candidates": len(angles),
    }


_MIN_BATCH = 64  # angles per full-bound call, at least (see _tighten)


def _tighten(
    bounds: AnalyticBounds,
    lb: np.ndarray,
    full: np.ndarray,
    open_: np.ndarray,
    j: int,
    best_n: float,
) -> None:
    """Give angle j, and every other open angle that could still be taken, the full
    analytic bound in one call: those whose weak bound is <= the best count, or before
    the first evaluation <= the least full bound among open angles (or j's own); and at
    least the ``_MIN_BATCH`` open angles of least weak bound (a call's fixed cost, numpy's
    per-call overhead, is that of a few dozen angles' own work). On the irregular
    40-vertex field at 12 m, j and one tie at weak bound 65 rose to 71, and the second
    call took the 191 angles of weak bound <= 71; with the floor, the first call's 64
    find the least full bound, 69, and the second takes the 67 left of weak bound <= 69
    (131 angles in all, the fewest that prove 69 the least; 0.13-0.25 ms of the
    search's 5.5 ms saved against floors of 32 or 128, or one call for all 229)."""
    tight = full & open_
    if math.isfinite(best_n):
        cap = best_n
    else:
        cap = lb[tight].min() if tight.any() else lb[j]
    todo = ~full & open_
    batch = todo & (lb <= cap)
    batch[j] = True
    if batch.sum() < _MIN_BATCH:
        rest = np.flatnonzero(todo)
        batch[rest[np.argsort(lb[rest], kind="stable")[:_MIN_BATCH]]] = True
    lb[batch] = bounds.full(np.flatnonzero(batch))
    full |= batch


def _branch_and_bound(
    bounds: AnalyticBounds,
    probe: Callable[[float], CentreLines],
    secondary: Callable[[CentreLines], float],
    count_at: Callable[[float], int],
) -> tuple[dict[float, tuple[int, float]], int]:
    """The objective at every angle whose key (count lower bound, second criterion) is
    below the best value found, taken in increasing (key, index) order; returns them and
    the number of probes.

    Each step does the cheapest thing that can raise the least key: full analytic bound
    (lazily, :func:`_tighten`: a weak bound is never above the full one, so the angle
    taken is the one the full bounds alone would give), then the probe (the centre
    lines: their scan-line bound, and the second criterion, -inf until known), then the
    layout (``count_at``: the objective there is the swath count and the second
    criterion already known, so the centre lines are not cut twice). A key only rises
    towards the objective, so an angle left when the least key reaches the best value
    cannot beat it.
    """
    angles = bounds.phis
    lb = bounds.weak.copy()
    sec = np.full(len(angles), -np.inf)
    full = np.zeros(len(angles), bool)
    open_ = np.ones(len(angles), bool)
    results: dict[float, tuple[int, float]] = {}
    best: tuple[float, float] = (math.inf, math.inf)
    while open_.any():
        idx = np.flatnonzero(open_)
        least = idx[lb[idx] == lb[idx].min()]
        j = int(least[np.argmin(sec[least])])  # least (bound, second criterion, index)
        if (int(lb[j]), float(sec[j])) >= best:
            break
        if not full[j]:
            _tighten(bounds, lb, full, open_, j, best[0])
        elif sec[j] == -np.inf:  # not probed yet (the criterion is a length, >= 0)
            lines = probe(float(angles[j]))
            lb[j] = max(int(lb[j]), lines.count)
            sec[j] = secondary(lines)
        else:
            phi = float(angles[j])
            results[phi] = (count_at(phi), float(sec[j]))
            best = min(best, results[phi])
            open_[j] = False
    return results, int(np.isfinite(sec).sum())
