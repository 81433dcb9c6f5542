"""Stage: swaths -- the strips of the inner region and the swath in each strip piece.

Everything is computed in the planning frame (swaths along +x). Strip ``i`` is the band
``y0 + i*w .. y0 + (i+1)*w`` of the (headland-reduced) region R; the swath is its centre
line, so the first swath lies w/2 inside R and ``n = ceil((H - tol) / w)`` strips leave
at most a ``tol`` wide strip at the far edge (tol = 1 % of w, at most 5 cm: not worth a
swath; reported as ``uncovered_m2``). Strip pieces lower than tol that the centre line
misses are left uncovered the same way.

A strip may cross R several times: each connected piece of ``strip & R`` is its own
swath, stretched over the piece's whole x-extent so the implement (w wide) covers it
completely. Where the centre line itself crosses a hole or notch inside one piece the
swath is split there, so swaths never run through a hole; notches narrower than w/2
(traced-boundary teeth) are bridged instead of splitting the swath.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon
from shapely.geometry.base import BaseGeometry

from .. import PlanningError
from .boundary import parts

N_EPS = 1e-9  # tolerance on H / w when counting strips
STRIP_TOLERANCE_FRACTION = 0.01  # uncovered strip not worth a swath: 1 % of w ...
STRIP_TOLERANCE_MAX_M = 0.05  # ... and never more than 5 cm
MAX_SWATHS = 200_000


def default_strip_tolerance(w: float) -> float:
    """Widest uncovered strip that is not worth an extra swath: 1 % of w, at most 5 cm.

    A rounded boundary (corners snapped to 1e-9 deg) makes a 23 m wide plot 23.00006 m
    wide; at w = 2.3 m a strict ``ceil(H / w)`` adds an 11th swath, 10 % of whose area
    lies outside the field, to cover a 0.06 mm strip. The strip is reported as uncovered
    area instead (plan metric ``uncovered_m2``).
    """
    return min(STRIP_TOLERANCE_FRACTION * w, STRIP_TOLERANCE_MAX_M)


def n_strips(extent: float, w: float, tol: float) -> int:
    """Strips of width w for an extent H, leaving at most ``tol`` uncovered at the far edge."""
    return max(1, math.ceil((extent - tol) / w - N_EPS))


def holes_of(fld: BaseGeometry) -> BaseGeometry:
    """Union of the field's holes (ponds, islands of trees)."""
    return shapely.union_all([Polygon(r) for p in parts(fld) for r in p.interiors])


@dataclass
class StripPiece:
    part: int
    strip: int
    y: float
    x0: float
    x1: float
    comp: Polygon
    full: np.ndarray | None
    links_up: list[int] = field(default_factory=list)


def _cut_at_holes(
    a: float, b: float, y: float, core: tuple[float, float] | None, holes: BaseGeometry | None
) -> tuple[float, float]:
    """Shorten a swath stretched over its strip piece so its line never enters a hole.

    Stretching a swath to the x-extent of its strip piece covers the wedges along slanted
    edges; along the outer boundary that is what a tractor does (h = 0: turn outside),
    but nobody drives into a pond, so at holes the wedge is left uncovered instead.
    """
    if holes is None:
        return a, b
    seg = LineString([(a, y), (b, y)])
    if not holes.intersects(seg):
        return a, b
    rest = [g for g in shapely.get_parts(seg.difference(holes)) if g.length > 1e-9]
    if not rest:
        return a, a
    if core is not None:
        m = 0.5 * (core[0] + core[1])
        for g in rest:
            if g.bounds[0] - 1e-9 <= m <= g.bounds[2] + 1e-9:
                return g.bounds[0], g.bounds[2]
    g = max(rest, key=lambda g: g.length)
    return g.bounds[0], g.bounds[2]


@dataclass
class _Strips:
    """The strips of one polygon q and their pieces, shared by the layout helpers."""

    q: Polygon
    w: float
    n: int
    edges: np.ndarray
    ys: np.ndarray
    bx0: float
    bx1: float
    holes: BaseGeometry | None
    comps: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=object))
    cb: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    c_start: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    c_end: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def owner(self, strip: int, x: float, y: float) -> int | None:
        """The piece of ``strip`` that contains (x, y)."""
        ci = range(self.c_start[strip], self.c_end[strip])
        if len(ci) == 1:
            return ci[0]
        for c in ci:
            cb = self.cb[c]
            if cb[0] - 1e-9 <= x <= cb[2] + 1e-9 and shapely.intersects_xy(self.comps[c], x, y):
                return c
        return None


def _strips(q: Polygon, w: float, tol: float, holes: BaseGeometry | None) -> _Strips:
    xmin, ymin, xmax, ymax = q.bounds
    n = n_strips(ymax - ymin, w, tol)
    if n > MAX_SWATHS:
        raise PlanningError(f"swath width {w} m gives more than {MAX_SWATHS} swaths")
    edges = ymin + np.arange(n + 1) * w
    return _Strips(q, w, n, edges, edges[:-1] + 0.5 * w, xmin - 1.0, xmax + 1.0, holes)


def _pieces(st: _Strips, tol: float) -> None:
    """Connected pieces of each strip & q (``comps``, sorted by strip)."""
    n, edges = st.n, st.edges
    # GEOS's rectangle clipper is ~3x faster than a general overlay; its output is not
    # guaranteed valid, so the rare invalid piece is repaired
    inter = np.array(
        [shapely.clip_by_rect(st.q, st.bx0, edges[i], st.bx1, edges[i + 1]) for i in range(n)],
        dtype=object,
    )
    bad = ~shapely.is_valid(inter)
    if bad.any():
        inter[bad] = shapely.make_valid(inter[bad])
    comps, cidx = shapely.get_parts(inter, return_index=True)
    ok = (shapely.get_type_id(comps) == 3) & (shapely.area(comps) > 1e-12)
    comps, cidx = comps[ok], cidx[ok]
    cb = shapely.bounds(comps)
    # a strip piece lower than the tolerance that the centre line misses (a boundary
    # vertex poking into the strip) is not worth a swath: it stays uncovered, reported.
    # A strip keeps at least one piece.
    if tol > 0 and len(comps):
        yc = st.ys[cidx]
        thin = ((cb[:, 3] - cb[:, 1]) < tol) & ((cb[:, 3] < yc) | (cb[:, 1] > yc))
        per_strip = np.bincount(cidx, minlength=n)
        thin_per_strip = np.bincount(cidx[thin], minlength=n)
        thin &= (per_strip - thin_per_strip)[cidx] > 0
        comps, cidx, cb = comps[~thin], cidx[~thin], cb[~thin]
    st.comps, st.cb = comps, cb
    st.c_start = np.searchsorted(cidx, np.arange(n))
    st.c_end = np.searchsorted(cidx, np.arange(n), side="right")


def _lines(st: _Strips, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounds (m, 4) and line index of the pieces of the horizontal lines y = ys inside q."""
    m = len(ys)
    cl = shapely.linestrings(
        np.stack([np.stack([np.full(m, st.bx0), ys], 1), np.stack([np.full(m, st.bx1), ys], 1)], 1)
    )
    segs, sidx = shapely.get_parts(shapely.intersection(cl, st.q), return_index=True)
    ok = shapely.get_type_id(segs) == 1
    sb, sidx = shapely.bounds(segs[ok]), sidx[ok]
    ok = sb[:, 2] - sb[:, 0] > 1e-9
    return sb[ok], sidx[ok]


def _full_intervals(st: _Strips) -> dict[int, np.ndarray]:
    """Per strip, the x-intervals where the whole strip column lies inside q."""
    strips = shapely.box(st.bx0, st.edges[:-1], st.bx1, st.edges[1:])
    dparts, didx = shapely.get_parts(shapely.difference(strips, st.q), return_index=True)
    ok = shapely.get_type_id(dparts) == 3
    db, didx = shapely.bounds(dparts[ok]), didx[ok]
    order = np.lexsort((db[:, 0], didx))
    didx, db = didx[order], db[order]
    starts = np.searchsorted(didx, np.arange(st.n))
    ends = np.searchsorted(didx, np.arange(st.n), side="right")
    out: dict[int, np.ndarray] = {}
    for i in range(st.n):
        # complement of the bad x-intervals inside [bx0, bx1]
        good: list[tuple[float, float]] = []
        cur = st.bx0
        for a, b in db[starts[i] : ends[i]][:, [0, 2]]:
            if a > cur:
                good.append((cur, a))
            cur = max(cur, b)
        if cur < st.bx1:
            good.append((cur, st.bx1))
        out[i] = np.asarray(good, float).reshape(-1, 2)
    return out


def _ranges(lo: float, hi: float, ivs: list[tuple[float, float]]) -> list[tuple[Any, ...]]:
    """Swath ranges of one piece from its centre-line intervals (touching ones merged)."""
    merged: list[list[float]] = []
    for a, b in sorted(ivs):
        if merged and a <= merged[-1][1] + 1e-7:
            merged[-1][1] = max(merged[-1][1], b)
        else:
            merged.append([a, b])
    if len(merged) <= 1:
        return [(lo, hi, tuple(merged[0]) if merged else None)]
    last = len(merged) - 1
    return [
        (lo if j == 0 else a, hi if j == last else b, (a, b)) for j, (a, b) in enumerate(merged)
    ]


def _candidates(st: _Strips, i: int, sb: np.ndarray) -> list[tuple[Any, ...]]:
    """(x0, x1, piece, centre-line core) of every swath candidate in strip i."""
    ci = range(st.c_start[i], st.c_end[i])
    per_comp: dict[int, list[tuple[float, float]]] = {c: [] for c in ci}
    for a, _, b, _ in sb:
        c = st.owner(i, 0.5 * (a + b), float(st.ys[i]))
        if c is not None:
            per_comp[c].append((a, b))
    cand = []
    for c in sorted(ci, key=lambda c: st.cb[c, 0]):
        for a, b, core in _ranges(st.cb[c, 0], st.cb[c, 2], per_comp[c]):
            a, b = _cut_at_holes(a, b, float(st.ys[i]), core, st.holes)
            if b - a > 1e-9:
                cand.append((a, b, c, core))
    return cand


def _group(st: _Strips, y: float, cand: list[tuple[Any, ...]]) -> list[list[Any]]:
    """Candidates joined across narrow notches: [x0, x1, pieces, core end] per swath.

    A notch narrower than half the working width does not split a swath: the implement
    cannot work it anyway, and traced boundaries are full of such teeth. Two swaths on
    the centre line merge when the gap between the centre-line intervals is < w/2 (the
    rule the centre-line count of :mod:`.centrelines` uses); a piece the centre line misses joins a
    neighbour closer than w/2.
    """
    groups: list[list[Any]] = []
    for a, b, c, core in sorted(cand, key=lambda t: (t[0], t[1])):
        if groups and a >= groups[-1][1] - 1e-9:
            g = groups[-1]
            gap_x = core[0] - g[3] if core is not None and g[3] is not None else a - g[1]
            seg = LineString([(g[1], y), (a, y)])
            if gap_x < 0.5 * st.w and (st.holes is None or not st.holes.intersects(seg)):
                g[1] = max(g[1], b)
                g[2].append(c)
                if core is not None:
                    g[3] = core[1]
                continue
        groups.append([a, b, [c], None if core is None else core[1]])
    return groups


def _link(st: _Strips, subs: list[StripPiece], subs_of_comp: dict[int, list[int]]) -> None:
    """Links between swaths of consecutive strips, through the pieces J of the strip edge
    lines inside q: each J belongs to one piece below and one above; two swaths are
    linked when both cover a common part of some J (they touch through the field)."""
    links: set[tuple[int, int]] = set()
    if st.n > 1:
        ye = st.edges[1:-1]
        jb, jidx = _lines(st, ye)
        for (ja, _, jz, _), k in zip(jb, jidx, strict=True):
            mx = 0.5 * (ja + jz)
            c_lo, c_hi = st.owner(k, mx, ye[k]), st.owner(k + 1, mx, ye[k])
            if c_lo is None or c_hi is None:
                continue
            for a in subs_of_comp.get(c_lo, []):
                for b in subs_of_comp.get(c_hi, []):
                    sa, sb_ = subs[a], subs[b]
                    if min(sa.x1, sb_.x1, jz) - max(sa.x0, sb_.x0, ja) > 1e-9:
                        links.add((a, b))
    for s in subs:
        s.links_up = []
    for a, b in links:
        subs[a].links_up.append(b)


def strip_layout(
    q: Polygon,
    w: float,
    part: int,
    with_full: bool,
    holes: BaseGeometry | None = None,
    tol: float = 0.0,
) -> list[StripPiece]:
    """Swaths of one polygon in the rotated frame (see module docstring)."""
    st = _strips(q, w, tol, holes)
    shapely.prepare(q)
    _pieces(st, tol)
    sb, sidx = _lines(st, st.ys)
    s_start = np.searchsorted(sidx, np.arange(st.n))
    s_end = np.searchsorted(sidx, np.arange(st.n), side="right")
    full = _full_intervals(st) if with_full else {}
    subs: list[StripPiece] = []
    subs_of_comp: dict[int, list[int]] = {}
    for i in range(st.n):
        if st.c_end[i] == st.c_start[i]:
            continue
        y = float(st.ys[i])
        for a, b, cs, _ in _group(st, y, _candidates(st, i, sb[s_start[i] : s_end[i]])):
            uniq = sorted(set(cs))
            for c in uniq:
                subs_of_comp.setdefault(c, []).append(len(subs))
            clip = st.comps[cs[0]] if len(uniq) == 1 else shapely.union_all(st.comps[uniq])
            subs.append(StripPiece(part, i, y, float(a), float(b), clip, full.get(i)))
    _link(st, subs, subs_of_comp)
    return subs
