"""Planar primitives, one home on the edge (and for the server's as-applied kernel).

* even-odd point-in-polygon: a point is inside when a ray to +x crosses an odd
  number of edges of all the polygon's rings (outer rings and holes alike), the
  edge (x0 y0)-(x1 y1) counting when ``(y0 > y) != (y1 > y)`` and the point lies
  left of it. ``crosses`` is that predicate, for scalars and numpy arrays alike;
  every point-in-polygon test of the agent (field boundary, cell rectangles, real
  cell shapes, the simulator's bookkeeping) goes through it;
* ``Polygons``: many polygons as one edge table (CSR), tested in bulk for
  (polygon, point) pairs, and the part of a segment inside a polygon (the
  driving line in a cell, the landing segment of metered mass: seed 001 eq. 17);
* ``GridHash``: a uniform grid over bounding boxes answering "which items may
  touch this point / box" in O(1).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np


def crosses(x0: Any, y0: Any, x1: Any, y1: Any, x: Any, y: Any) -> Any:
    """Does the +x ray from (x, y) cross edge (x0 y0)-(x1 y1)? (the even-odd rule's step).

    Works on floats and on broadcasting numpy arrays; a horizontal edge never crosses.
    """
    if isinstance(y0, float | int) and isinstance(y, float | int):
        return (y0 > y) != (y1 > y) and x < x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return ((y0 > y) != (y1 > y)) & (x < x0 + (y - y0) * (x1 - x0) / (y1 - y0))


def in_flat_rings(rings: Sequence[Sequence[float]], x: float, y: float) -> bool:
    """Scalar even-odd test over rings given as flat x y lists (closing vertex optional)."""
    inside = False
    for ring in rings:
        x0, y0 = ring[-2], ring[-1]
        for i in range(0, len(ring), 2):
            x1, y1 = ring[i], ring[i + 1]
            if (y0 > y) != (y1 > y) and x < x0 + (y - y0) * (x1 - x0) / (y1 - y0):
                inside = not inside
            x0, y0 = x1, y1
    return inside


def ring_edges(ring: Any) -> np.ndarray:
    """(m, 4) edges x0 y0 x1 y1 of one ring (flat list or (m, 2)); zero-length edges dropped."""
    p = np.asarray(ring, dtype=float).reshape(-1, 2)
    q = np.roll(p, -1, axis=0)
    e = np.column_stack([p, q])
    return np.asarray(e[(e[:, 0] != e[:, 2]) | (e[:, 1] != e[:, 3])])


def points_in_edges(edges: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Vectorised even-odd test of many points against one polygon given as an edge table.

    Only the (edge, point) pairs whose y-band matches are formed (points sorted by
    y, one searchsorted per edge), so a 1000-edge boundary costs a few pairs per point.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    out = np.zeros(len(x), dtype=bool)
    if len(edges) == 0 or len(x) == 0:
        return out
    order = np.argsort(y, kind="stable")
    ys = y[order]
    lo = np.searchsorted(ys, np.minimum(edges[:, 1], edges[:, 3]), side="left")
    hi = np.searchsorted(ys, np.maximum(edges[:, 1], edges[:, 3]), side="left")
    cnt = np.maximum(hi - lo, 0)
    e = np.repeat(np.arange(len(edges)), cnt)
    k = np.repeat(lo, cnt) + np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    pt = order[k]
    ed = edges[e]
    hit = crosses(ed[:, 0], ed[:, 1], ed[:, 2], ed[:, 3], x[pt], y[pt])
    return np.asarray(np.bincount(pt[hit], minlength=len(x)) % 2 == 1)


class Region:
    """One polygon (a field: outer rings and holes, even-odd) with an index of its edges,
    for bulk point tests and segment cuts."""

    def __init__(self, rings: Sequence[Any]) -> None:
        self.edges = np.vstack([ring_edges(r) for r in rings]) if len(rings) else np.zeros((0, 4))
        e = self.edges
        self.bbox = np.column_stack(
            [np.minimum(e[:, 0], e[:, 2]), np.minimum(e[:, 1], e[:, 3]),
             np.maximum(e[:, 0], e[:, 2]), np.maximum(e[:, 1], e[:, 3])]
        )  # fmt: skip
        self.index = GridHash(self.bbox)

    def contains(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return points_in_edges(self.edges, x, y)

    def segment_crossings(self, p0: np.ndarray, p1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(segment index, t) where segment p0[i]-p1[i] crosses an edge, 0 < t < 1."""
        boxes = np.column_stack(
            [np.minimum(p0[:, 0], p1[:, 0]), np.minimum(p0[:, 1], p1[:, 1]),
             np.maximum(p0[:, 0], p1[:, 0]), np.maximum(p0[:, 1], p1[:, 1])]
        )  # fmt: skip
        q, k = self.index.pairs(boxes, self.bbox)
        return _crossings(self.edges[k], p0[q], p1[q], q)


def _crossings(
    e: np.ndarray, a: np.ndarray, b: np.ndarray, who: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Segment a[i]-b[i] against edge e[i]: (who[i], t) of the proper crossings, 0 < t < 1."""
    d = b - a
    f = e[:, 2:4] - e[:, 0:2]
    den = d[:, 0] * f[:, 1] - d[:, 1] * f[:, 0]
    w = e[:, 0:2] - a
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[:, 0] * f[:, 1] - w[:, 1] * f[:, 0]) / den
        u = (w[:, 0] * d[:, 1] - w[:, 1] * d[:, 0]) / den
    ok = (np.abs(den) > 1e-12) & (t > 0) & (t < 1) & (u >= 0) & (u <= 1)
    return who[ok], t[ok]


class Polygons:
    """Polygons (cells) as one edge table: polygon k owns edge rows ``start[k]:start[k+1]``.

    Built from 4-corner rectangles (any vertex order) with optional real shapes
    (index -> rings as flat x y lists) replacing some of them.
    """

    def __init__(self, rings: Sequence[Sequence[Any]]) -> None:
        parts = [
            np.vstack([ring_edges(r) for r in rr]) if len(rr) else np.zeros((0, 4)) for rr in rings
        ]
        self.n = len(parts)
        cnt = np.asarray([len(p) for p in parts], dtype=np.int64)
        self.start = np.concatenate([[0], np.cumsum(cnt)]).astype(np.int64)
        self.edges = np.vstack(parts) if self.n else np.zeros((0, 4))
        bx0 = np.full(self.n, np.inf)
        by0 = np.full(self.n, np.inf)
        bx1 = np.full(self.n, -np.inf)
        by1 = np.full(self.n, -np.inf)
        if len(self.edges):
            owner = np.repeat(np.arange(self.n), cnt)
            e = self.edges
            np.minimum.at(bx0, owner, np.minimum(e[:, 0], e[:, 2]))
            np.minimum.at(by0, owner, np.minimum(e[:, 1], e[:, 3]))
            np.maximum.at(bx1, owner, np.maximum(e[:, 0], e[:, 2]))
            np.maximum.at(by1, owner, np.maximum(e[:, 1], e[:, 3]))
        self.bbox = np.column_stack([bx0, by0, bx1, by1])

    @classmethod
    def from_cells(
        cls, corners: Any, shapes: dict[int, list[list[float]]] | None = None
    ) -> Polygons:
        c = np.asarray(corners, dtype=float).reshape(-1, 8)
        shapes = shapes or {}
        return cls([shapes[k] if k in shapes else [c[k]] for k in range(len(c))])

    def _pair_edges(self, poly: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(pair index, edge row) for every edge of every pair's polygon."""
        cnt = self.start[poly + 1] - self.start[poly]
        pair = np.repeat(np.arange(len(poly)), cnt)
        off = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        return pair, np.repeat(self.start[poly], cnt) + off

    def contains(self, poly: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Even-odd: is point i inside polygon poly[i]? (vectorised over pairs)."""
        poly = np.asarray(poly, dtype=np.int64)
        pair, row = self._pair_edges(poly)
        e = self.edges[row]
        hit = crosses(e[:, 0], e[:, 1], e[:, 2], e[:, 3], x[pair], y[pair])
        return np.asarray(np.bincount(pair[hit], minlength=len(poly)) % 2 == 1)

    def segment_crossings(
        self, poly: np.ndarray, p0: np.ndarray, p1: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(pair index, t) where segment p0[i]-p1[i] crosses an edge of polygon poly[i], 0<t<1."""
        poly = np.asarray(poly, dtype=np.int64)
        pair, row = self._pair_edges(poly)
        return _crossings(self.edges[row], p0[pair], p1[pair], pair)


def split_segments(
    n_seg: int, seg: np.ndarray, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pieces of n_seg segments cut at parameters (seg, t): (piece's segment, t0, t1)."""
    s = np.concatenate([np.arange(n_seg), np.arange(n_seg), seg])
    tt = np.concatenate([np.zeros(n_seg), np.ones(n_seg), t])
    order = np.lexsort((tt, s))
    s, tt = s[order], tt[order]
    same = s[1:] == s[:-1]
    keep = same & (tt[1:] > tt[:-1])
    return s[:-1][keep], tt[:-1][keep], tt[1:][keep]


class GridHash:
    """Uniform grid over items' bounding boxes (n, 4: x0 y0 x1 y1): O(1) candidate queries."""

    def __init__(self, bbox: np.ndarray, bucket_m: float | None = None) -> None:
        bbox = np.asarray(bbox, dtype=float).reshape(-1, 4)
        self.n = len(bbox)
        if self.n == 0:
            self.x0 = self.y0 = 0.0
            self.b = 1.0
            self.nx = self.ny = 1
            self.start = np.zeros(2, dtype=np.int64)
            self.items = np.zeros(0, dtype=np.int64)
            self._itemlist: list[int] = []
            self._startlist: list[int] = [0, 0]
            return
        bx0, by0, bx1, by1 = bbox.T
        size = bucket_m or float(np.median(np.maximum(bx1 - bx0, by1 - by0)))
        self.b = max(size, 1e-3)
        self.x0, self.y0 = float(bx0.min()), float(by0.min())
        self.nx = int((bx1.max() - self.x0) / self.b) + 1
        self.ny = int((by1.max() - self.y0) / self.b) + 1
        item, key = self._cover(bx0, by0, bx1, by1)
        order = np.lexsort((item, key))
        key, item = key[order], item[order]
        self.items = item
        self.start = np.searchsorted(key, np.arange(self.nx * self.ny + 1))
        self._itemlist = item.tolist()
        self._startlist = self.start.tolist()

    def _cover(
        self, bx0: np.ndarray, by0: np.ndarray, bx1: np.ndarray, by1: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(box index, bucket key) for every bucket each box overlaps (clipped to the grid)."""
        i0 = np.clip(np.floor((bx0 - self.x0) / self.b), 0, self.nx - 1).astype(np.int64)
        i1 = np.clip(np.floor((bx1 - self.x0) / self.b), 0, self.nx - 1).astype(np.int64)
        j0 = np.clip(np.floor((by0 - self.y0) / self.b), 0, self.ny - 1).astype(np.int64)
        j1 = np.clip(np.floor((by1 - self.y0) / self.b), 0, self.ny - 1).astype(np.int64)
        ni, nj = i1 - i0 + 1, j1 - j0 + 1
        cnt = ni * nj
        box = np.repeat(np.arange(len(bx0)), cnt)
        k = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        ii = np.repeat(i0, cnt) + k % np.repeat(ni, cnt)
        jj = np.repeat(j0, cnt) + k // np.repeat(ni, cnt)
        return box, jj * self.nx + ii

    def candidates(self, x: float, y: float) -> list[int]:
        """Items whose box touches the bucket of (x, y) (scalar, the agent's per-fix path)."""
        fx = (x - self.x0) / self.b
        fy = (y - self.y0) / self.b
        if not (0.0 <= fx < self.nx and 0.0 <= fy < self.ny):
            return []
        i, j = int(fx), int(fy)
        k = j * self.nx + i
        return self._itemlist[self._startlist[k] : self._startlist[k + 1]]

    def pairs(self, boxes: np.ndarray, item_bbox: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(query, item) pairs whose boxes overlap, sorted by query then item, unique."""
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        if self.n == 0 or len(boxes) == 0:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        bx0, by0, bx1, by1 = boxes.T
        off = (
            (bx1 < self.x0)
            | (by1 < self.y0)
            | (bx0 > self.x0 + self.nx * self.b)
            | (by0 > self.y0 + self.ny * self.b)
        )
        q, key = self._cover(bx0, by0, bx1, by1)
        keep = ~off[q]
        q, key = q[keep], key[keep]
        cnt = self.start[key + 1] - self.start[key]
        qq = np.repeat(q, cnt)
        pos = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        it = self.items[np.repeat(self.start[key], cnt) + pos]
        ib = np.asarray(item_bbox, dtype=float)[it]
        bq = boxes[qq]
        ov = (ib[:, 0] <= bq[:, 2]) & (ib[:, 2] >= bq[:, 0])
        ov &= (ib[:, 1] <= bq[:, 3]) & (ib[:, 3] >= bq[:, 1])
        qq, it = qq[ov], it[ov]
        if len(qq) == 0:
            return qq, it
        code = np.unique(qq * self.n + it)
        return code // self.n, code % self.n
