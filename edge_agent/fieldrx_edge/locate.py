"""Which cell is under a point: path-ordered search with a grid-hash fallback.

Seed 001 sec. 2.3: the terminal finds its cell following the path order and
drops finished cells from later checks. A machine driving the path is almost
always in the current cell or one of the next few, so the search starts there
(O(1) per fix). When it leaves the path (turns, a detour, driving back), a
uniform grid hash over the cells' bounding boxes answers in O(1) as well.

``FieldBoundary`` answers "inside the field?" with even-odd ray casting over
all rings (outer rings and holes), restricted to the edges that span the
point's horizontal band, so a 1000-vertex boundary costs a handful of edge
tests per fix. The agent must never apply outside the field or in a hole.

Cells are the package's 4-corner rectangles (seed 001 Table 1), except where
the package gives a cell's real shape (field edge, holes, headland rings:
``JobPackage.shape_*``): there a point is in the cell only if it is in the
shape (even-odd over its rings, behind a bounding-box test), so overlapping
rectangles of neighbouring headland cells no longer claim each other's points.

Every even-odd test and the grid hash are ``fieldrx_edge.planar``'s (one home).
"""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np

from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.planar import GridHash, Polygons, crosses, in_flat_rings, points_in_edges


class Where(IntEnum):
    INSIDE = 0
    OUTSIDE = 1
    HOLE = 2


def boundary_rings(boundary: dict) -> list[tuple[list[list[float]], bool]]:
    """(ring, is_hole) for a GeoJSON Polygon/MultiPolygon (or bare coordinates)."""
    if "coordinates" in boundary:
        coords = boundary["coordinates"]
        gtype = boundary.get("type", "Polygon")
    else:
        raise ValueError("boundary_utm must have 'coordinates'")
    polys = coords if gtype == "MultiPolygon" else [coords]
    out = []
    for poly in polys:
        for i, ring in enumerate(poly):
            out.append((ring, i > 0))
    return out


class FieldBoundary:
    """Point-in-field test (even-odd over rings, holes excluded) with a y-band edge index."""

    def __init__(self, boundary_utm: dict, band_m: float | None = None) -> None:
        edges = []
        for ring, hole in boundary_rings(boundary_utm):
            pts = [(float(p[0]), float(p[1])) for p in ring]
            if len(pts) > 1 and pts[0] == pts[-1]:
                pts = pts[:-1]
            for i in range(len(pts)):
                x0, y0 = pts[i]
                x1, y1 = pts[(i + 1) % len(pts)]
                if y0 != y1:
                    edges.append((x0, y0, x1, y1, hole))
        if not edges:
            raise ValueError("field boundary has no edges")
        e = np.array([[a, b, c, d] for a, b, c, d, _ in edges])
        self.ymin = float(min(e[:, 1].min(), e[:, 3].min()))
        self.ymax = float(max(e[:, 1].max(), e[:, 3].max()))
        self.xmin = float(min(e[:, 0].min(), e[:, 2].min()))
        self.xmax = float(max(e[:, 0].max(), e[:, 2].max()))
        n_bands = max(1, min(4096, len(edges)))
        self.band = band_m or max((self.ymax - self.ymin) / n_bands, 1e-6)
        nb = int(math.floor((self.ymax - self.ymin) / self.band)) + 1
        self._bands: list[list[tuple[float, float, float, float, bool]]] = [[] for _ in range(nb)]
        for x0, y0, x1, y1, hole in edges:
            lo = int((min(y0, y1) - self.ymin) / self.band)
            hi = int((max(y0, y1) - self.ymin) / self.band)
            for b in range(lo, min(hi, nb - 1) + 1):
                self._bands[b].append((x0, y0, x1, y1, hole))
        self._edges = np.array([[a, b, c, d, h] for a, b, c, d, h in edges], dtype=float)

    def where(self, x: float, y: float) -> Where:
        if not (self.ymin <= y <= self.ymax and self.xmin <= x <= self.xmax):
            return Where.OUTSIDE
        b = int((y - self.ymin) / self.band)
        if b >= len(self._bands):
            b = len(self._bands) - 1
        outer = hole = False
        for x0, y0, x1, y1, is_hole in self._bands[b]:
            # planar.crosses, inlined: this runs for every fix
            if (y0 > y) != (y1 > y) and x < x0 + (y - y0) * (x1 - x0) / (y1 - y0):
                if is_hole:
                    hole = not hole
                else:
                    outer = not outer
        if not outer:
            return Where.OUTSIDE
        return Where.HOLE if hole else Where.INSIDE

    def contains(self, x: float, y: float) -> bool:
        return self.where(x, y) == Where.INSIDE

    def contains_many(self, xy: np.ndarray) -> np.ndarray:
        """Vectorised even-odd test for many points (simulator bookkeeping)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        return points_in_edges(self._edges[:, :4], xy[:, 0], xy[:, 1])


Shape = tuple[tuple[float, float, float, float], tuple[tuple[float, ...], ...]]


def _in_shape(sh: Shape, x: float, y: float) -> bool:
    """Point in a cell shape: bounding box first, then even-odd over all its rings."""
    bx0, by0, bx1, by1 = sh[0]
    if x < bx0 or x > bx1 or y < by0 or y > by1:
        return False
    return in_flat_rings(sh[1], x, y)


def _make_shape(rings: list[list[float]]) -> Shape:
    flat = [tuple(float(v) for v in r) for r in rings]
    xs = [v for r in flat for v in r[0::2]]
    ys = [v for r in flat for v in r[1::2]]
    return (min(xs), min(ys), max(xs), max(ys)), tuple(flat)


class CellLocator:
    """Path-ordered cell search with finished-cell dropping and a grid-hash fallback.

    ``locate(x, y)`` returns the cell index (0-based position in path order) or
    -1. ``finished`` marks cells already applied; the forward search skips
    them, while the fallback still reports them (so overlap control can tell a
    point is in an already-applied cell).

    ``shapes`` (path index -> rings as flat x y lists, ``JobPackage.cell_shapes``)
    replaces the rectangle of those cells; the grid hash then covers the
    shape's bounding box.
    """

    def __init__(
        self,
        corners_utm: np.ndarray | list[float],
        window: int = 6,
        bucket_m: float | None = None,
        shapes: dict[int, list[list[float]]] | None = None,
    ) -> None:
        c = np.asarray(corners_utm, dtype=float).reshape(-1, 8)
        self.n = len(c)
        self.corners = c
        # each rectangle as a one-ring tuple, ready for planar.in_flat_rings
        self._quads: list[tuple[tuple[float, ...]]] = [(tuple(row),) for row in c.tolist()]
        self._shapes: list[Shape | None] = [None] * self.n
        for k, rings in (shapes or {}).items():
            self._shapes[k] = _make_shape(rings)
        self.n_shapes = sum(1 for sh in self._shapes if sh is not None)
        self.finished = np.zeros(self.n, dtype=bool)
        self._fin = self.finished  # same buffer; numpy bool indexing is fast enough
        self.window = window
        self.current = 0
        self.fallbacks = 0
        xs, ys = c[:, 0::2], c[:, 1::2]
        bbox = np.column_stack([xs.min(1), ys.min(1), xs.max(1), ys.max(1)])
        for k, sh in enumerate(self._shapes):
            if sh is not None:
                bbox[k] = sh[0]
        self.grid = GridHash(bbox, bucket_m)
        self._shapes_rings = shapes or {}

    def reset(self, current: int = 0) -> None:
        self.current = max(0, min(current, self.n - 1)) if self.n else 0

    def candidates(self, x: float, y: float) -> list[int]:
        """Cells whose bounding box touches the grid-hash bucket of (x, y)."""
        return self.grid.candidates(x, y)

    def shaped_mask(self) -> np.ndarray:
        """Per cell: does it carry its real shape?"""
        return np.array([sh is not None for sh in self._shapes], dtype=bool)

    def contains(self, k: int, x: float, y: float) -> bool:
        """Is (x, y) in cell k (its shape if it has one, else its rectangle)?"""
        sh = self._shapes[k]
        return in_flat_rings(self._quads[k], x, y) if sh is None else _in_shape(sh, x, y)

    def locate(self, x: float, y: float) -> int:
        """Cell under (x, y), searching forward in path order first."""
        quads, shapes, fin = self._quads, self._shapes, self.finished
        cur = self.current
        n = self.n
        if n == 0:
            return -1
        if not fin[cur]:
            sh = shapes[cur]
            if in_flat_rings(quads[cur], x, y) if sh is None else _in_shape(sh, x, y):
                return cur
        end = min(n, cur + 1 + self.window)
        for k in range(cur + 1, end):
            if not fin[k]:
                sh = shapes[k]
                if in_flat_rings(quads[k], x, y) if sh is None else _in_shape(sh, x, y):
                    self.current = k
                    return k
        # off the path: spatial fallback; prefer an unfinished cell, lowest path index
        self.fallbacks += 1
        best = -1
        for k in self.grid.candidates(x, y):
            sh = shapes[k]
            if in_flat_rings(quads[k], x, y) if sh is None else _in_shape(sh, x, y):
                if not fin[k]:
                    self.current = k
                    return k
                if best < 0:
                    best = k
        return best

    def distance_to_cell(self, idx: int, x: float, y: float) -> float:
        """Distance from a point to a cell (0 inside): border hysteresis against GNSS jitter."""
        if self.contains(idx, x, y):
            return 0.0
        sh = self._shapes[idx]
        rings = self._quads[idx] if sh is None else sh[1]
        best = math.inf
        for q in rings:
            x0, y0 = q[-2], q[-1]
            for i in range(0, len(q), 2):
                x1, y1 = q[i], q[i + 1]
                dx, dy = x1 - x0, y1 - y0
                L2 = dx * dx + dy * dy
                t = 0.0 if L2 == 0 else max(0.0, min(1.0, ((x - x0) * dx + (y - y0) * dy) / L2))
                best = min(best, math.hypot(x - x0 - t * dx, y - y0 - t * dy))
                x0, y0 = x1, y1
        return best

    def locate_naive(self, x: float, y: float) -> int:
        """Baseline: test every cell (vectorised numpy). For benchmarks and tests only."""
        if self.n == 0:
            return -1
        c = self.corners
        inside = np.zeros(self.n, dtype=bool)
        for a in range(0, 8, 2):
            b = (a + 2) % 8
            inside ^= crosses(c[:, a], c[:, a + 1], c[:, b], c[:, b + 1], x, y)
        if self.n_shapes:
            if not hasattr(self, "_polygons"):
                self._shaped = np.flatnonzero(self.shaped_mask())
                self._polygons = Polygons.from_cells(
                    c[self._shaped],
                    {i: self._shapes_rings[int(k)] for i, k in enumerate(self._shaped)},
                )
            m = len(self._shaped)
            inside[self._shaped] = self._polygons.contains(
                np.arange(m), np.full(m, float(x)), np.full(m, float(y))
            )
        hits = np.flatnonzero(inside)
        return int(hits[0]) if len(hits) else -1


def locator_for_job(job: JobPackage) -> tuple[CellLocator, FieldBoundary]:
    return CellLocator(job.corners_utm, shapes=job.cell_shapes()), FieldBoundary(job.boundary_utm)
