"""Shortest non-working paths inside the field (weighted visibility graph).

Connections between swaths must stay inside the field and never cross a hole (
Fields2Cover's Dubins turns leave small plots and cross ponds). A shortest path inside
a polygon with holes runs straight or bends only at boundary vertices, so a visibility
graph over the vertices of the field (shrunk by a small clearance) gives exact shortest
paths. With headland passes, driving across the worked inner area is penalised
(``avoid`` region, cost factor ``avoid_factor`` per metre inside it), so transfers
between blocks run along the headland unless a crossing saves a lot (e.g. to reach the
headland around a pond, which is an island inside the inner area).
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy.sparse.csgraph import shortest_path
from shapely.geometry import LineString, MultiPolygon, Point, Polygon
from shapely.geometry.base import BaseGeometry
from shapely.ops import nearest_points

_MAX_NODES = 250
_SAMPLES = 16  # points per segment to estimate its length inside the avoided area


def _ring_coords(poly: Polygon) -> list[np.ndarray]:
    rings = [np.asarray(poly.exterior.coords)[:-1]]
    rings += [np.asarray(r.coords)[:-1] for r in poly.interiors]
    return rings


def _nodes(geom: BaseGeometry) -> np.ndarray:
    polys = [p for p in shapely.get_parts(geom) if isinstance(p, Polygon) and not p.is_empty]
    pts = [c for p in polys for c in _ring_coords(p)]
    return np.concatenate(pts) if pts else np.zeros((0, 2))


class FieldRouter:
    """Shortest paths inside ``field`` kept ``clearance`` metres off its boundary."""

    def __init__(
        self,
        field: Polygon | MultiPolygon,
        clearance: float = 0.05,
        avoid: BaseGeometry | None = None,
        avoid_factor: float = 4.0,
    ) -> None:
        domain = field.buffer(-clearance, join_style="mitre", mitre_limit=5.0)
        if domain.is_empty or domain.area < 0.5 * field.area:
            domain = field
        tol = clearance / 2.0
        nodes = _nodes(domain)
        while len(nodes) > _MAX_NODES:
            tol *= 2.0
            domain = domain.simplify(tol, preserve_topology=True).intersection(field)
            nodes = _nodes(domain)
        self.domain = domain
        shapely.prepare(self.domain)
        # snap targets strictly inside, so visibility tests from snapped points are robust
        snap = domain.buffer(-1e-3, join_style="mitre", mitre_limit=5.0)
        self._snap = snap if not snap.is_empty else domain
        self.avoid = None
        self.extra = max(0.0, avoid_factor - 1.0)
        if avoid is not None and not avoid.is_empty and self.extra > 0:
            av = avoid.buffer(-0.01, join_style="mitre", mitre_limit=5.0)
            av = av.simplify(0.25, preserve_topology=True)
            if not av.is_empty:
                self.avoid = av
                shapely.prepare(self.avoid)
                # corners of the inner area (just outside it) let paths hug the headland
                grown = avoid.buffer(0.05, join_style="mitre", mitre_limit=5.0)
                ring_pts = _nodes(grown.simplify(0.25, preserve_topology=True))
                if len(ring_pts) and len(nodes) + len(ring_pts) <= 2 * _MAX_NODES:
                    inside = shapely.covers(self.domain, shapely.points(ring_pts))
                    nodes = np.concatenate([nodes, ring_pts[inside]])
        self.nodes = nodes
        self._vis_cache: dict[tuple[float, float], tuple[np.ndarray, np.ndarray]] = {}
        n = len(nodes)
        if n:
            i, j = np.triu_indices(n, 1)
            segs = shapely.linestrings(np.stack([nodes[i], nodes[j]], axis=1))
            ok = shapely.covers(self.domain, segs)
            d = self._cost(segs[ok], np.hypot(*(nodes[i[ok]] - nodes[j[ok]]).T))
            dist = np.zeros((n, n))
            dist[i[ok], j[ok]] = np.maximum(d, 1e-12)
            dist[j[ok], i[ok]] = np.maximum(d, 1e-12)
            self.dist, self.pred = shortest_path(
                dist, method="D", directed=False, return_predecessors=True
            )
        else:
            self.dist = np.zeros((0, 0))
            self.pred = np.zeros((0, 0), dtype=np.int32)

    def _cost(self, segs: np.ndarray, lengths: np.ndarray) -> np.ndarray:
        """Length plus the penalty for the part inside the avoided (inner) area.

        The inside share is estimated from evenly spaced sample points (vectorised
        point-in-polygon); exact overlays for every graph edge cost seconds on real
        boundaries with hundreds of vertices.
        """
        if self.avoid is None or len(segs) == 0:
            return lengths
        c = shapely.get_coordinates(segs).reshape(-1, 2, 2)
        f = (np.arange(_SAMPLES) + 0.5) / _SAMPLES
        pts = c[:, :1, :] + f[None, :, None] * (c[:, 1:, :] - c[:, :1, :])
        inside = shapely.contains_xy(self.avoid, pts[..., 0], pts[..., 1]).mean(axis=1)
        return np.asarray(lengths + self.extra * inside * lengths)

    def _inside(self, p: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """Point p moved into the domain (nearest point) plus the stub that got it there."""
        pt = Point(p)
        if self.domain.covers(pt):
            return p, []
        q = nearest_points(self._snap, pt)[0]
        return np.array([q.x, q.y]), [p]

    def path(self, a: np.ndarray, b: np.ndarray) -> LineString:
        """Cheapest path from a to b inside the field (stubs if a or b lie outside)."""
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
        seg = LineString([a, b])
        direct_ok = bool(self.domain.covers(seg))
        if direct_ok and (self.avoid is None or not self.avoid.intersects(seg)):
            return [a, b]  # straight and not across the inner area: nothing is shorter
        if len(self.nodes) == 0:
            return [a, b]
        direct = (
            float(self._cost(np.array([seg]), np.array([seg.length]))[0]) if direct_ok else np.inf
        )
        da, va = self._visible(a)
        db, vb = self._visible(b)
        if not va.any() or not vb.any():
            return [a, b]
        ia = np.flatnonzero(va)
        ib = np.flatnonzero(vb)
        tot = da[ia][:, None] + self.dist[np.ix_(ia, ib)] + db[ib][None, :]
        k = int(np.argmin(tot))
        if not np.isfinite(tot.flat[k]) or tot.flat[k] >= direct:
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
        key = (round(float(p[0]), 6), round(float(p[1]), 6))
        hit = self._vis_cache.get(key)
        if hit is not None:
            return hit
        segs = shapely.linestrings(
            np.stack([np.broadcast_to(p, self.nodes.shape), self.nodes], axis=1)
        )
        vis = shapely.covers(self.domain, segs)
        cost = np.full(len(self.nodes), np.inf)
        cost[vis] = self._cost(segs[vis], np.hypot(*(self.nodes[vis] - p).T))
        if len(self._vis_cache) < 20_000:
            self._vis_cache[key] = (cost, vis)
        return cost, vis

    def distance(self, a: np.ndarray, b: np.ndarray) -> float:
        """Length of :meth:`path` (metres driven, without the penalty)."""
        return float(self.path(a, b).length)
