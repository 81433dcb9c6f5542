"""Swath-count lower bounds as functions of the heading (the heading search's pruning).

The planner's swath count at heading phi (:func:`.swaths.strip_layout`) needs one GEOS
clip per strip; these bounds need none. Every bound here is <= that count at every
angle, so :func:`.headings.optimal_phi` may skip any angle whose bound is not below the
best count found (branch and bound), and still never need more swaths than a 1-degree
brute-force scan.

* :func:`extent_lower_bounds` -- every strip of a part holds at least one swath: the
  number of strips, from the part's width across phi (rotating calipers over the hull).
* :class:`AnalyticBounds` (:func:`analytic_lower_bounds`) -- the scan-line form,
  evaluated for all angles at once from the vertices alone (no per-strip work,
  ``O(vertices x angles)``): centre-line intervals (edge crossings / 2), minus an upper
  bound on the notches narrower than w/2 that the planner bridges (``weak``), plus
  the isolated spike tips that no centre line reaches (each such tip is a strip piece
  of its own, hence a swath; ``full``: the tips are found for every angle at once, their
  isolation tested only for the angles the search may still take).

The finer, per-angle scan-line bound (the centre-line intervals with the exact w/2
bridging rule) is the heading search's probe, ``CentreLines.count`` of
:mod:`.centrelines`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import Polygon
from shapely.geometry.base import BaseGeometry
from shapely.geometry.polygon import orient

from .swaths import N_EPS

_EPS = 1e-9  # metres: ties at band edges are resolved towards the smaller bound
_CHAIN_STEPS = 12  # vertices followed from a spike tip before giving the tip up


@dataclass(frozen=True)
class _Vertices:
    """The vertices of one part (all rings, interior on the left), relative to its centroid."""

    xy: np.ndarray  # (V, 2)
    prev: np.ndarray  # (V,) index of the previous vertex of the same ring
    next: np.ndarray  # (V,) index of the next vertex of the same ring (edge i = i -> next[i])
    exterior: np.ndarray  # (V,) bool: vertex of the exterior ring
    convex: np.ndarray  # (V,) bool: interior angle < 180 deg (the part lies in the wedge)
    origin: np.ndarray  # (2,) the centroid the coordinates are relative to

    @classmethod
    def of(cls, p: Polygon) -> _Vertices:
        p = orient(p, 1.0)  # exterior counter-clockwise, holes clockwise: interior on the left
        c0 = np.asarray(p.centroid.coords[0])
        xy, prev, nxt, ext = [], [], [], []
        off = 0
        for r, ring in enumerate([p.exterior, *p.interiors]):
            c = np.asarray(ring.coords)[:-1] - c0
            k = len(c)
            idx = np.arange(k)
            xy.append(c)
            prev.append(off + (idx - 1) % k)
            nxt.append(off + (idx + 1) % k)
            ext.append(np.full(k, r == 0))
            off += k
        v = np.concatenate(xy)
        pv, nx = np.concatenate(prev), np.concatenate(nxt)
        e_in, e_out = v - v[pv], v[nx] - v
        cross = e_in[:, 0] * e_out[:, 1] - e_in[:, 1] * e_out[:, 0]
        return cls(v, pv, nx, np.concatenate(ext), cross > 0, c0)


class _Lines:
    """The centre lines y0 + (k + 1/2) w, k < n, of one part at every angle (columns)."""

    def __init__(self, y0: np.ndarray, n: np.ndarray, w: float) -> None:
        self.y0, self.n, self.w = y0, n, w

    def below(self, y: np.ndarray) -> np.ndarray:
        """Number of centre lines strictly below y (per angle column)."""
        k = np.ceil((y - self.y0) / self.w - 0.5)
        return np.asarray(np.minimum(np.maximum(k, 0), self.n).astype(np.int64))

    def between(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Number of centre lines with lo <= y < hi (0 where hi <= lo)."""
        return np.asarray(np.maximum(self.below(hi) - self.below(lo), 0))


def _narrow_notch_lines(
    v: _Vertices, X: np.ndarray, Y: np.ndarray, lines: _Lines, w: float
) -> np.ndarray:
    """Upper bound, per angle, on the centre-line gaps narrower than w/2 that the planner
    bridges (each one interval fewer).

    A gap on a centre line lies between two boundary edges. Two edges sharing a vertex
    bound a gap only at a reflex local extremum (a notch tip): the gap widens linearly
    from the tip, so the lines closer to it than where the width reaches w/2 are counted
    (:func:`_notch_tip_lines`). Two edges not sharing a vertex bound a narrow gap only
    if they come closer than w/2 (angle-independent, :func:`_edge_pairs_within`); every
    line on which they are less than w/2 apart is counted. The sum over-counts, which
    keeps the bound a lower bound.
    """
    gaps = _notch_tip_lines(v, X, Y, lines, w)
    i, j = _edge_pairs_within(v, 0.5 * w + _EPS)
    if len(i):
        lo, hi = _closer_than(X, Y, v.next, i, j, 0.5 * w)
        gaps += lines.between(lo - _EPS, hi + _EPS).sum(0)
    return gaps


_PAIRWISE_MAX_EDGES = 256  # up to here all edge pairs' boxes are compared at once


def _edge_pairs_within(v: _Vertices, d: float) -> tuple[np.ndarray, np.ndarray]:
    """The pairs (i, j), i < j, of edges not sharing a vertex that come within d.

    Candidates are the pairs whose bounding boxes, grown by d, overlap: all pairs at
    once up to ``_PAIRWISE_MAX_EDGES`` edges (cheaper than building a tree for a few
    dozen), an STRtree beyond; GEOS decides the distance of the candidates."""
    a, b = v.xy, v.xy[v.next]
    segs = shapely.linestrings(np.stack([a, b], 1))
    if len(segs) > _PAIRWISE_MAX_EDGES:
        i, j = shapely.STRtree(segs).query(segs, predicate="dwithin", distance=d)
    else:
        lo, hi = np.minimum(a, b) - d, np.maximum(a, b) + d
        near = (lo[:, None, 0] <= hi[None, :, 0]) & (lo[None, :, 0] <= hi[:, None, 0])
        near &= (lo[:, None, 1] <= hi[None, :, 1]) & (lo[None, :, 1] <= hi[:, None, 1])
        i, j = np.nonzero(np.triu(near, 1))
        close = shapely.dwithin(segs[i], segs[j], d)
        i, j = i[close], j[close]
    keep = (i < j) & (v.next[i] != j) & (v.next[j] != i)
    return i[keep], j[keep]


def _notch_tip_lines(
    v: _Vertices, X: np.ndarray, Y: np.ndarray, lines: _Lines, w: float
) -> np.ndarray:
    """Per angle, the centre lines that cross a notch (reflex local extremum) less than
    w/2 wide, along the notch's own two edges.

    A line is not counted when its strip cannot bridge the gap: the notch crosses the
    whole strip (tip outside the band, both edges through it), so the two sides are
    separate strip pieces, and their x-extents overlap (a slanted notch), so the planner
    never joins their swaths (:func:`.swaths._group` joins only non-overlapping ones).
    """
    out = np.zeros(Y.shape[1], dtype=np.int64)
    rows = np.flatnonzero(~v.convex)
    if not len(rows):
        return out
    Yr, Yp, Yn = Y[rows], Y[v.prev[rows]], Y[v.next[rows]]
    tip = ((Yp > Yr) & (Yn > Yr)) | ((Yp < Yr) & (Yn < Yr))
    ri, ai = np.nonzero(tip)
    if not len(ri):
        return out
    vi = rows[ri]
    y, x = Y[vi, ai], X[vi, ai]
    yp, yn, xp, xn = Y[v.prev[vi], ai], Y[v.next[vi], ai], X[v.prev[vi], ai], X[v.next[vi], ai]
    sgn = np.where(yp > y, 1.0, -1.0)  # +1: the notch opens upwards
    dyp, dyn = np.abs(yp - y), np.abs(yn - y)
    kp, kn = (xp - x) / (yp - y), (xn - x) / (yn - y)
    s = np.abs(kp - kn)
    with np.errstate(divide="ignore"):
        reach = np.minimum(dyp, dyn)
        zone = np.minimum(reach, np.where(s > 0, 0.5 * w / s, np.inf)) + _EPS
    y0, n = lines.y0[ai], lines.n[ai]
    lo = np.where(sgn > 0, y - _EPS, y - zone)
    hi = np.where(sgn > 0, y + zone, y + _EPS)
    k0 = np.minimum(np.maximum(np.ceil((lo - y0) / w - 0.5), 0), n).astype(np.int64)
    k1 = np.minimum(np.maximum(np.ceil((hi - y0) / w - 0.5), 0), n).astype(np.int64)
    cnt = np.maximum(k1 - k0, 0)
    if not cnt.any():  # most tips are crossed by no line in their zone, often all
        return out
    # one row per (tip, line in its zone)
    t = np.repeat(np.arange(len(cnt)), cnt)
    m = np.arange(len(t)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    y, x, kp, kn, sgn, reach = (a[t] for a in (y, x, kp, kn, sgn, reach))
    yk = y0[t] + (k0[t] + m + 0.5) * w
    ba, bb = yk - 0.5 * w, yk + 0.5 * w
    d_near = np.where(sgn > 0, ba - y, y - bb)  # tip to the band, along the notch
    d_far = np.where(sgn > 0, bb - y, y - ba)
    spans = (d_near > _EPS) & (d_far < reach - _EPS)
    xpa, xpb, xna, xnb = (
        x + (ba - y) * kp,
        x + (bb - y) * kp,
        x + (ba - y) * kn,
        x + (bb - y) * kn,
    )
    p_left = (xpa + xpb) < (xna + xnb)
    left_max = np.where(p_left, np.maximum(xpa, xpb), np.maximum(xna, xnb))
    right_min = np.where(p_left, np.minimum(xna, xnb), np.minimum(xpa, xpb))
    bridged = ~(spans & (left_max > right_min + 1e-7))
    return np.bincount(ai[t[bridged]], minlength=len(out)).astype(np.int64)


def _closer_than(
    X: np.ndarray, Y: np.ndarray, nxt: np.ndarray, i: np.ndarray, j: np.ndarray, d: float
) -> tuple[np.ndarray, np.ndarray]:
    """Per edge pair (i, j) and angle, the heights [lo, hi) at which both edges cross a
    horizontal line less than d apart (hi <= lo: none). The x-distance of two edges is
    linear in the height over their common height range, so the set is one interval."""
    xa, ya, xb, yb = X[i], Y[i], X[nxt[i]], Y[nxt[i]]
    xc, yc, xd, yd = X[j], Y[j], X[nxt[j]], Y[nxt[j]]
    lo = np.maximum(np.minimum(ya, yb), np.minimum(yc, yd))
    hi = np.minimum(np.maximum(ya, yb), np.maximum(yc, yd))
    with np.errstate(divide="ignore", invalid="ignore"):
        ki, kj = (xb - xa) / (yb - ya), (xd - xc) / (yd - yc)
        d_lo = (xa + (lo - ya) * ki) - (xc + (lo - yc) * kj)
        dk = ki - kj
        y1 = lo + (d - d_lo) / dk
        y2 = lo + (-d - d_lo) / dk
    flat = ~np.isfinite(ki) | ~np.isfinite(kj)  # a horizontal edge crosses no line
    same = ~flat & ((dk == 0) | ~np.isfinite(y1) | ~np.isfinite(y2))
    a = np.where(same, np.where(np.abs(d_lo) < d, lo, hi), np.maximum(lo, np.minimum(y1, y2)))
    b = np.where(same, hi, np.minimum(hi, np.maximum(y1, y2)))
    return np.where(flat, np.inf, a), np.where(flat, -np.inf, b)  # flat: an empty set


def _segments_hit_boxes(
    xa: np.ndarray,
    ya: np.ndarray,
    xb: np.ndarray,
    yb: np.ndarray,
    box: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> np.ndarray:
    """Whether segment (xa, ya)-(xb, yb) meets the closed box (x0, x1, y0, y1); arrays
    broadcast (segments along axis 0, boxes along axis 1). Separating axes: the
    segment's bounding box overlaps the box, and the box's corners are not all strictly
    on one side of the segment's line."""
    x0, x1, y0, y1 = box
    hit = (np.minimum(xa, xb) <= x1) & (np.maximum(xa, xb) >= x0)
    hit &= (np.minimum(ya, yb) <= y1) & (np.maximum(ya, yb) >= y0)
    dx, dy = xb - xa, yb - ya
    u0, u1 = (x0 - xa) * dy, (x1 - xa) * dy  # side of corner (x, y): (x-xa)dy - (y-ya)dx
    v0, v1 = (y0 - ya) * dx, (y1 - ya) * dx
    s00, s01, s10, s11 = u0 - v0, u0 - v1, u1 - v0, u1 - v1
    lo = np.minimum(np.minimum(s00, s01), np.minimum(s10, s11))
    hi = np.maximum(np.maximum(s00, s01), np.maximum(s10, s11))
    return np.asarray(hit & (lo <= 0) & (hi >= 0))


@dataclass(frozen=True)
class _EdgeBoxes:
    """The edges i -> next[i] of one part at every angle, one row per angle (so that a
    tip's row is one contiguous read): end points and height ranges."""

    xa: np.ndarray  # (angles, V)
    ya: np.ndarray
    xb: np.ndarray
    yb: np.ndarray
    ylo: np.ndarray
    yhi: np.ndarray

    @classmethod
    def of(cls, X: np.ndarray, Y: np.ndarray, nxt: np.ndarray) -> _EdgeBoxes:
        xa, ya = np.ascontiguousarray(X.T), np.ascontiguousarray(Y.T)
        xb, yb = xa[:, nxt], ya[:, nxt]
        return cls(xa, ya, xb, yb, np.minimum(ya, yb), np.maximum(ya, yb))


def _edges_meet_boxes(
    edges: _EdgeBoxes,
    rows: np.ndarray,
    box: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    own: np.ndarray,
) -> np.ndarray:
    """Per box (at the angle of row ``rows`` of ``edges``), whether any edge except the
    box's ``own`` edges (a row per box, -1 for none) meets it: height ranges first,
    the exact test (:func:`_segments_hit_boxes`) on the rest."""
    x0, x1, y0, y1 = box
    near = edges.ylo[rows] <= y1[:, None]  # the band is thin: few edges reach it
    near &= edges.yhi[rows] >= y0[:, None]
    t, k = np.nonzero(own >= 0)
    near[t, own[t, k]] = False
    ti, ei = np.nonzero(near)
    r = rows[ti]
    ends = (edges.xa[r, ei], edges.ya[r, ei], edges.xb[r, ei], edges.yb[r, ei])
    hit = _segments_hit_boxes(*ends, (x0[ti], x1[ti], y0[ti], y1[ti]))
    out = np.zeros(len(rows), bool)
    out[ti[hit]] = True
    return out


def _tip_chains(
    v: _Vertices,
    X: np.ndarray,
    Y: np.ndarray,
    vi: np.ndarray,
    ai: np.ndarray,
    edge_y: np.ndarray,
    down: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Walk from each tip vertex along both sides of the ring (previous and next
    vertices) while the boundary moves monotonically away from the tip, until it leaves
    the band at ``edge_y``.

    Returns (both sides monotone and left within _CHAIN_STEPS, x min, x max of the two
    chains inside the band, the chains' edge indices: a row per tip, -1 where none).

    Both sides walk in one set of arrays and only the chains still walking are stepped
    (most leave the band within a step or two): the cost is numpy's per-call overhead."""
    n = len(vi)
    fwd = np.arange(2 * n) >= n  # the first n walk to the previous vertex
    ai, edge_y, down, cur = (np.concatenate([t, t]) for t in (ai, edge_y, down, vi))
    y, x = Y[cur, ai], X[cur, ai]
    xmin, xmax = x.copy(), x.copy()
    ok = np.ones(2 * n, bool)
    done = np.zeros(2 * n, bool)
    edges = np.full((2 * n, _CHAIN_STEPS), -1)
    act = np.arange(2 * n)  # chains still walking: monotone so far and inside the band
    steps = 0
    with np.errstate(divide="ignore", invalid="ignore"):  # once: it costs a few microseconds
        for k in range(_CHAIN_STEPS):
            steps = k + 1
            c, a, f = cur[act], ai[act], fwd[act]
            nb = np.where(f, v.next[c], v.prev[c])
            edges[act, k] = np.where(f, c, nb)
            yn, xn, yc, xc0, dn, ey = Y[nb, a], X[nb, a], y[act], x[act], down[act], edge_y[act]
            mono = np.where(dn, yn < yc, yn > yc)
            left = np.where(dn, yn < ey - _EPS, yn > ey + _EPS)
            xc = np.where(left, xc0 + (ey - yc) / (yn - yc) * (xn - xc0), xn)
            xmin[act] = np.minimum(xmin[act], xc)
            xmax[act] = np.maximum(xmax[act], xc)
            ok[act] &= mono
            done[act] |= left
            cur[act], y[act], x[act] = nb, yn, xn
            act = act[mono & ~left]
            if not len(act):
                break
    ok &= done
    return (
        ok[:n] & ok[n:],
        np.minimum(xmin[:n], xmin[n:]),
        np.maximum(xmax[:n], xmax[n:]),
        np.hstack([edges[:n, :steps], edges[n:, :steps]]),
    )


@dataclass(frozen=True)
class _SpikeCandidates:
    """Spike tips of one part, at every angle, whose two chains leave the band: the
    angle column of each, its box (x0, x1, y0, y1) and its chains' own edges (a row per
    tip, -1 for none). Whether a tip counts is its isolation (:func:`_isolated`)."""

    ai: np.ndarray
    box: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
    own: np.ndarray


def _spike_candidates(
    v: _Vertices, X: np.ndarray, Y: np.ndarray, lines: _Lines, tol: float
) -> _SpikeCandidates:
    """The spike tips of the exterior ring that no centre line reaches, per angle
    (before the isolation test of :func:`_isolated`; each isolated one is a swath the
    crossing count misses).

    A convex local maximum v of the exterior ring with a + tol <= y_v < centre (a: its
    strip's lower edge), from which the boundary falls monotonically on both sides until
    it leaves the band below a: the part of the field between these two chains is a
    strip piece (or several) that the centre line misses, at least tol high (so the
    planner keeps it). Its box is the band, within w/2 of the chains in x. Minima
    mirror this.
    """
    w = lines.w
    rows = np.flatnonzero(v.convex & v.exterior)
    Yr, Yp, Yn = Y[rows], Y[v.prev[rows]], Y[v.next[rows]]
    a = lines.y0 + np.floor((Yr - lines.y0) / w) * w
    ok = (a >= lines.y0 - _EPS) & (a < lines.y0 + lines.n * w - _EPS)
    up = ok & (Yp < Yr) & (Yn < Yr) & (Yr >= a + tol) & (Yr < a + 0.5 * w - _EPS)
    dn = ok & (Yp > Yr) & (Yn > Yr) & (Yr > a + 0.5 * w + _EPS) & (Yr <= a + w - tol)
    ri, ai = np.nonzero(up | dn)
    vi, down, a = rows[ri], up[ri, ai], a[ri, ai]
    edge_y = np.where(down, a, a + w)
    ok, lo, hi, own = _tip_chains(v, X, Y, vi, ai, edge_y, down)
    sel = np.flatnonzero(ok)  # only these can count
    a = a[sel]
    box = (lo[sel] - 0.5 * w, hi[sel] + 0.5 * w, a - _EPS, a + w + _EPS)
    return _SpikeCandidates(ai[sel], box, own[sel])


def _isolated(
    tips: _SpikeCandidates,
    sel: np.ndarray,
    edges: _EdgeBoxes,
    obstacles: tuple[np.ndarray, np.ndarray],
    phis: np.ndarray,
) -> np.ndarray:
    """Per tip ``sel``, whether no other edge (of any ring, or of a field hole) meets its
    box: then the planner can join its strip piece to no neighbour, and it is a swath
    of its own."""
    ai = tips.ai[sel]
    box = (tips.box[0][sel], tips.box[1][sel], tips.box[2][sel], tips.box[3][sel])
    keep = ~_edges_meet_boxes(edges, ai, box, tips.own[sel])
    ob_a, ob_b = obstacles
    if len(ob_a) and keep.any():
        sn, cs = np.sin(phis[ai]), np.cos(phis[ai])
        ox_a = ob_a[:, :1] * cs + ob_a[:, 1:] * sn
        oy_a = -ob_a[:, :1] * sn + ob_a[:, 1:] * cs
        ox_b = ob_b[:, :1] * cs + ob_b[:, 1:] * sn
        oy_b = -ob_b[:, :1] * sn + ob_b[:, 1:] * cs
        keep &= ~_segments_hit_boxes(ox_a, oy_a, ox_b, oy_b, box).any(0)
    return keep


@dataclass(frozen=True)
class _ConcavePart:
    """What :meth:`AnalyticBounds.full` needs of a non-convex part (all angles)."""

    n: np.ndarray  # strips
    intervals: np.ndarray  # centre-line intervals, narrow gaps bridged (an under-count)
    tips: _SpikeCandidates
    edges: _EdgeBoxes
    obstacles: tuple[np.ndarray, np.ndarray]  # the field's hole edges, relative to the part


class AnalyticBounds:
    """The analytic swath-count lower bound of some parts at given angles, in two steps.

    The constructor computes, per part and for every angle at once, the strips (their
    number is :func:`extent_lower_bounds`' bound) and the centre-line intervals: each
    edge crosses the centre lines between its end points' heights (a closed form), every
    line crosses the boundary twice per interval, so the intervals summed over lines
    are half the crossings; minus the narrow gaps the planner bridges
    (:func:`_narrow_notch_lines`, an over-count). ``weak`` is the bound from these alone.
    It also finds the spike tips no centre line reaches (:func:`_spike_candidates`).
    :meth:`full` adds, for the angles asked, those of them that stand alone in their
    strip (:func:`_isolated`: every tip against every edge, the dearest test), so the
    heading search asks for it only on the angles it may still take. The tips only add,
    so ``weak`` is never above the full bound: both are lower bounds. ``holes`` are the
    field's holes (the planner cuts swaths at them; a tip near one is not counted).
    """

    def __init__(
        self,
        parts: list[Polygon],
        w: float,
        phis: np.ndarray,
        tol: float,
        holes: BaseGeometry | None = None,
    ) -> None:
        self.w, self.tol = w, tol
        self.phis = np.asarray(phis, float)
        sn, cs = np.sin(self.phis), np.cos(self.phis)
        hole_rings = [
            np.asarray(h.exterior.coords)
            for h in (shapely.get_parts(holes) if holes is not None and not holes.is_empty else [])
        ]
        ob_a = np.concatenate([r[:-1] for r in hole_rings] or [np.zeros((0, 2))])
        ob_b = np.concatenate([r[1:] for r in hole_rings] or [np.zeros((0, 2))])
        self.weak = np.zeros(len(self.phis), dtype=np.int64)
        self._concave: list[_ConcavePart] = []
        for p in parts:
            v = _Vertices.of(p)
            X = v.xy[:, :1] * cs + v.xy[:, 1:] * sn
            Y = -v.xy[:, :1] * sn + v.xy[:, 1:] * cs
            ye = Y[v.exterior]
            y0 = ye.min(0)
            n = np.maximum(1, np.ceil((ye.max(0) - y0 - tol) / w - N_EPS)).astype(np.int64)
            if v.exterior.all() and v.convex.all():
                self.weak += n  # a convex part: one piece per strip, the strip count
                continue
            lines = _Lines(y0, n, w)
            k = lines.below(Y)  # edge i crosses the lines between k[i] and k[next[i]]
            crossings = np.abs(k[v.next] - k).sum(0)
            intervals = crossings // 2 - _narrow_notch_lines(v, X, Y, lines, w)
            self.weak += np.maximum(n, intervals)
            self._concave.append(
                _ConcavePart(
                    n,
                    intervals,
                    _spike_candidates(v, X, Y, lines, tol),
                    _EdgeBoxes.of(X, Y, v.next),
                    (ob_a - v.origin, ob_b - v.origin),
                )
            )

    def full(self, idx: np.ndarray) -> np.ndarray:
        """The full analytic bound at the angles ``phis[idx]`` (``weak`` + isolated
        spike tips)."""
        lb = self.weak[idx].copy()
        asked = np.zeros(len(self.phis), bool)
        asked[idx] = True
        for part in self._concave:
            sel = np.flatnonzero(asked[part.tips.ai])
            keep = _isolated(part.tips, sel, part.edges, part.obstacles, self.phis)
            tips = np.bincount(part.tips.ai[sel[keep]], minlength=len(self.phis))[idx]
            n, iv = part.n[idx], part.intervals[idx]
            lb += np.maximum(n, iv + tips) - np.maximum(n, iv)
        return np.asarray(lb)


def analytic_lower_bounds(
    parts: list[Polygon],
    w: float,
    phis: np.ndarray,
    tol: float,
    holes: BaseGeometry | None = None,
) -> np.ndarray:
    """Swath-count lower bound for every angle in ``phis`` at once, from the vertices
    (:class:`AnalyticBounds`, full bound everywhere)."""
    ab = AnalyticBounds(parts, w, phis, tol, holes)
    return ab.full(np.arange(len(ab.phis)))
