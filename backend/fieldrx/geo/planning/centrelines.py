"""The centre-line layout: the swaths' centre lines cut by the region, from its vertices.

At heading phi, centre line k of a part is y = y0 + (k + 1/2) w in the planning frame
(the line its strip's swath runs on). Cutting every line with the part's rings (pure
numpy, no GEOS) gives the centre-line intervals; gaps narrower than w/2 are bridged, as
the planner bridges such notches (:func:`.swaths._group`). Two uses:

* the scan-line swath-count lower bound (``CentreLines.count``): every strip holds at
  least one swath, and one per centre-line interval (the heading search's probe, on the
  few angles the analytic bounds of :mod:`.bounds` cannot prune);
* the heading objective's second criterion (:func:`nonworking_estimate`): the turn and
  transfer distance of the intervals driven as swaths. It needs no swath layout, so the
  heading search can rank angles with equal swath-count bounds by it and lay out only
  the best (ties in the count cost one layout each before).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from shapely.geometry import Polygon

from .swaths import n_strips

_LINK_EPS = 1e-7  # metres: intervals of consecutive lines must overlap by more to link


@dataclass(frozen=True)
class CentreLines:
    """The centre-line intervals of some parts at one heading, sorted by (line, x0).

    ``line`` numbers lines globally (part after part, one unused number between parts so
    no two parts' lines are consecutive); ``count`` is the swath-count lower bound.
    """

    line: np.ndarray
    y: np.ndarray
    x0: np.ndarray
    x1: np.ndarray
    count: int


@dataclass(frozen=True)
class _Rings:
    """One part's rings relative to the frame's origin: edges a -> b, exterior vertices."""

    a: np.ndarray
    b: np.ndarray
    ext: np.ndarray

    @classmethod
    def of(cls, p: Polygon, origin: np.ndarray) -> _Rings:
        ext = np.asarray(p.exterior.coords) - origin
        rings = [ext] + [np.asarray(r.coords) - origin for r in p.interiors]
        a = np.concatenate([r[:-1] for r in rings])
        b = np.concatenate([r[1:] for r in rings])
        return cls(a, b, ext)


def _part_lines(
    r: _Rings, w: float, sn: float, cs: float, tol: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """(line, y, x0, x1) of one part's centre-line intervals, and its number of strips."""
    a, b, ext = r.a, r.b, r.ext
    ya, yb = -a[:, 0] * sn + a[:, 1] * cs, -b[:, 0] * sn + b[:, 1] * cs
    ye = -ext[:, 0] * sn + ext[:, 1] * cs
    y0 = ye.min()
    n = n_strips(ye.max() - y0, w, tol)
    ys = y0 + (np.arange(n) + 0.5) * w
    # edge e crosses the lines lo[e] <= k < hi[e] (half-open: every line an even number)
    lo = np.searchsorted(ys, np.minimum(ya, yb), side="left")
    cnt = np.searchsorted(ys, np.maximum(ya, yb), side="left") - lo
    e = np.repeat(np.arange(len(a)), cnt)
    line = np.repeat(lo, cnt) + (np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt))
    xa, xb = a[e, 0] * cs + a[e, 1] * sn, b[e, 0] * cs + b[e, 1] * sn
    x = xa + (ys[line] - ya[e]) / (yb[e] - ya[e]) * (xb - xa)
    order = np.lexsort((x, line))
    line, x = line[order], x[order]
    li, x0, x1 = line[0::2], x[0::2], x[1::2]
    if not len(li):  # a part no centre line crosses (a sliver thinner than w / 2)
        return li, ys, x0, x1, n
    kept = ~((li[1:] == li[:-1]) & (x0[1:] - x1[:-1] < 0.5 * w))  # gap not bridged
    starts, ends = np.concatenate(([True], kept)), np.concatenate((kept, [True]))
    return li[starts], ys, x0[starts], x1[ends], n


class CentreLineCutter:
    """The centre-line layout of some parts at any heading, in the frame rotating about
    ``origin`` (the planning frame's, so brute force and search see the same numbers);
    the rings are read once (the heading search cuts a few headings of one region)."""

    def __init__(self, parts: list[Polygon], w: float, tol: float, origin: np.ndarray) -> None:
        self.w, self.tol = w, tol
        self._rings = [_Rings.of(p, origin) for p in parts]

    def __call__(self, phi: float) -> CentreLines:
        """The centre-line intervals at heading phi."""
        sn, cs = math.sin(phi), math.cos(phi)
        lines, ys, x0s, x1s = [], [], [], []
        off, count = 0, 0
        for r in self._rings:
            li, yk, x0, x1, n = _part_lines(r, self.w, sn, cs, self.tol)
            count += int(np.maximum(1, np.bincount(li, minlength=n)).sum())
            lines.append(li + off)
            ys.append(yk[li])
            x0s.append(x0)
            x1s.append(x1)
            off += n + 1
        if len(lines) == 1:
            return CentreLines(lines[0], ys[0], x0s[0], x1s[0], count)
        if not lines:
            z = np.zeros(0)
            return CentreLines(z.astype(np.int64), z, z, z, 0)
        cat = np.concatenate
        return CentreLines(cat(lines), cat(ys), cat(x0s), cat(x1s), count)


def chains(cl: CentreLines) -> tuple[np.ndarray, np.ndarray]:
    """Boustrophedon blocks of the intervals: maximal chains of intervals on consecutive
    lines linked uniquely (one overlapping interval above, one below), as
    :func:`.decomposition._blocks` chains the swaths. Returns the intervals in chain
    order and each chain's start in that order (chains ordered by their first interval)."""
    m = len(cl.line)
    # intervals are disjoint and sorted within a line, so (line, x) keys are monotone and
    # the intervals of line k + 1 overlapping [x0, x1] are one index range
    base = float(cl.x0.min()) if m else 0.0
    span = (float(cl.x1.max()) - base + 10.0) if m else 1.0
    k_start = cl.line * span + (cl.x0 - base)
    k_end = cl.line * span + (cl.x1 - base)
    above = (cl.line + 1) * span - base
    j_lo = np.searchsorted(k_end, above + cl.x0 + _LINK_EPS, side="right")
    up = np.maximum(np.searchsorted(k_start, above + cl.x1 - _LINK_EPS, side="left") - j_lo, 0)
    down = np.bincount(
        np.repeat(j_lo, up) + (np.arange(up.sum()) - np.repeat(np.cumsum(up) - up, up)),
        minlength=m,
    )
    unique = up == 1
    unique[unique] = down[j_lo[unique]] == 1
    nxt = np.where(unique, j_lo, -1).tolist()
    has_prev = np.zeros(m, bool)
    has_prev[j_lo[unique]] = True
    order: list[int] = []
    heads = np.flatnonzero(~has_prev).tolist()
    starts = []
    for k in heads:
        starts.append(len(order))
        while k >= 0:
            order.append(k)
            k = nxt[k]
    return np.asarray(order, np.int64), np.asarray(starts, np.int64)


def _block_turns(cl: CentreLines, order: np.ndarray, starts: np.ndarray, size: np.ndarray) -> float:
    """Straight turn lengths inside the blocks (``size`` intervals from ``starts`` in
    ``order``), each block in its better parity (the planner chooses whether a block's
    first pass runs +x or -x)."""
    if len(order) < 2:
        return 0.0
    block = np.repeat(np.arange(len(starts)), size)
    pos = np.arange(len(order)) - starts[block]
    same = block[1:] == block[:-1]  # turn from order[t] to order[t + 1]
    a, b = order[:-1][same], order[1:][same]
    dy = cl.y[b] - cl.y[a]
    right = np.hypot(cl.x1[b] - cl.x1[a], dy)
    left = np.hypot(cl.x0[b] - cl.x0[a], dy)
    even = pos[:-1][same] % 2 == 0
    tb, nb = block[:-1][same], len(starts)
    par_a = np.bincount(tb, np.where(even, right, left), nb)
    par_b = np.bincount(tb, np.where(even, left, right), nb)
    return float(np.minimum(par_a, par_b).sum())


def _hops(cl: CentreLines, order: np.ndarray, starts: np.ndarray, size: np.ndarray) -> float:
    """Greedy block-to-block hops: from the end of the first block to the nearest block
    entry, and so on (each block entered at its first interval's x0 and left at its last
    one's far end, first pass +x)."""
    first, last = order[starts], order[starts + size - 1]
    ex = np.where(size % 2 == 1, cl.x1[last], cl.x0[last])
    d = np.hypot(ex[:, None] - cl.x0[first][None, :], cl.y[last][:, None] - cl.y[first][None, :])
    d[:, 0] = np.inf
    total, cur = 0.0, 0
    for _ in range(len(starts) - 1):
        k = int(np.argmin(d[cur]))
        total += float(d[cur, k])
        d[:, k] = np.inf
        cur = k
    return total


def nonworking_estimate(cl: CentreLines) -> float:
    """Turns inside the blocks + greedy hops from block to block (nearest entry next),
    all straight lines: the heading objective's tie-break between equal swath counts.

    It ranks headings (a block is entered at its first interval's x0, as the layout-based
    estimate before it did); the planner then orders and configures the blocks exactly.
    """
    if not len(cl.line):
        return 0.0
    order, starts = chains(cl)
    size = np.diff(starts, append=len(order))
    return _block_turns(cl, order, starts, size) + _hops(cl, order, starts, size)
