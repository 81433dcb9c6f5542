"""Shortest non-working paths inside the field (visibility graph).

Connections between swaths must stay inside the field and never cross a hole
(issue 3; Fields2Cover's Dubins turns leave small plots and cross ponds). The
shortest path inside a polygon with holes runs straight or bends only at
boundary vertices, so a visibility graph over the vertices of the field,
shrunk by a small clearance, gives exact shortest paths.
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy.sparse.csgraph import shortest_path
from shapely.geometry import LineString, MultiPolygon, Point, Polygon
from shapely.ops import nearest_points

_MAX_NODES = 400


def _ring_coords(poly: Polygon) -> list[np.ndarray]:
    rings = [np.asarray(poly.exterior.coords)[:-1]]
    rings += [np.asarray(r.coords)[:-1] for r in poly.interiors]
    return rings


class FieldRouter:
    """Shortest paths inside ``field`` kept ``clearance`` metres off its boundary."""

    def __init__(self, field: Polygon | MultiPolygon, clearance: float = 0.05) -> None:
        domain = field.buffer(-clearance, join_style="mitre", mitre_limit=5.0)
        if domain.is_empty or domain.area < 0.5 * field.area:
            domain = field
        tol = clearance / 2.0
        nodes = self._nodes(domain)
        while len(nodes) > _MAX_NODES:
            tol *= 2.0
            domain = domain.simplify(tol, preserve_topology=True).intersection(field)
            nodes = self._nodes(domain)
        self.domain = domain
        shapely.prepare(self.domain)
        # snap targets strictly inside, so visibility tests from snapped points are robust
        snap = domain.buffer(-1e-3, join_style="mitre", mitre_limit=5.0)
        self._snap = snap if not snap.is_empty else domain
        self.nodes = nodes
        n = len(nodes)
        dist = np.full((n, n), np.inf)
        if n:
            i, j = np.triu_indices(n, 1)
            segs = shapely.linestrings(np.stack([nodes[i], nodes[j]], axis=1))
            ok = shapely.covers(self.domain, segs)
            d = np.hypot(*(nodes[i] - nodes[j]).T)
            dist[i[ok], j[ok]] = d[ok]
            dist[j[ok], i[ok]] = d[ok]
            np.fill_diagonal(dist, 0.0)
            self.dist, self.pred = shortest_path(
                np.where(np.isinf(dist), 0.0, dist),
                method="D",
                directed=False,
                return_predecessors=True,
            )
        else:
            self.dist = dist
            self.pred = np.zeros((0, 0), dtype=np.int32)

    @staticmethod
    def _nodes(domain: Polygon | MultiPolygon) -> np.ndarray:
        polys = list(domain.geoms) if isinstance(domain, MultiPolygon) else [domain]
        pts = [c for p in polys if not p.is_empty for c in _ring_coords(p)]
        return np.concatenate(pts) if pts else np.zeros((0, 2))

    def _inside(self, p: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """Point p moved into the domain (nearest point) plus the stub that got it there."""
        pt = Point(p)
        if self.domain.covers(pt):
            return p, []
        q = nearest_points(self._snap, pt)[0]
        q = np.array([q.x, q.y])
        return q, [p]

    def path(self, a: np.ndarray, b: np.ndarray) -> LineString:
        """Shortest path from a to b inside the field (stubs if a or b lie outside)."""
        a = np.asarray(a, float)
        b = np.asarray(b, float)
        a_in, pre = self._inside(a)
        b_in, post = self._inside(b)
        mid = self._inner_path(a_in, b_in)
        coords = pre + mid + ([b] if post else [])
        out = [coords[0]]
        for c in coords[1:]:
            if np.hypot(*(c - out[-1])) > 1e-9:
                out.append(c)
        if len(out) == 1:
            out.append(out[0])
        return LineString(out)

    def _inner_path(self, a: np.ndarray, b: np.ndarray) -> list[np.ndarray]:
        if self.domain.covers(LineString([a, b])) or len(self.nodes) == 0:
            return [a, b]
        da, va = self._visible(a)
        db, vb = self._visible(b)
        if not va.any() or not vb.any():
            return [a, b]
        ia = np.flatnonzero(va)
        ib = np.flatnonzero(vb)
        tot = da[ia][:, None] + self.dist[np.ix_(ia, ib)] + db[ib][None, :]
        k = int(np.argmin(tot))
        if not np.isfinite(tot.flat[k]):
            return [a, b]
        u, v = ia[k // len(ib)], ib[k % len(ib)]
        chain = [v]
        while chain[-1] != u:
            p = self.pred[u, chain[-1]]
            if p < 0:
                return [a, b]
            chain.append(p)
        chain.reverse()
        return [a] + [self.nodes[c] for c in chain] + [b]

    def _visible(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        segs = shapely.linestrings(
            np.stack([np.broadcast_to(p, self.nodes.shape), self.nodes], axis=1)
        )
        vis = shapely.covers(self.domain, segs)
        return np.hypot(*(self.nodes - p).T), vis

    def distance(self, a: np.ndarray, b: np.ndarray) -> float:
        """Length of :meth:`path`."""
        return float(self.path(a, b).length)
