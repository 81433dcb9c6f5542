"""The one in-memory cell type: a plan's grid cells in path order, as numpy columns.

Seed 001 sec. 1.2 cuts the planned path every L metres into cells one implement
width wide and numbers them in path order (Table 1: four counter-clockwise
corners per cell). Here the corners are rear-right, front-right, front-left,
rear-left relative to the driving direction (counter-clockwise). Every part of
FieldRx that holds cells in memory holds a :class:`Cells`: the grid builder
(``geo.grid.build_grid``), the cell store (``fieldrx.store``), rate models and
interpolation (``agronomy``), exports and job packages (``formats``), the
as-applied report. Columns, not objects per cell, so 870k-cell grids stay
vectorised.

What a cell is, stated once:

* ``corners_utm`` (n, 4, 2): the nominal implement footprint (seed 001 Table 1);
* ``polygons_utm`` (n,): the real cell, clipped to the field. A cell cut in two
  by a notch or hole stays whole (a MultiPolygon), never "its largest part";
* ``area_m2``: the real cell's area;
* ``centroids_utm``: the one centre rule (``cell_centres``): area centroid, or a
  point on the surface when the centroid falls outside the cell;
* ``drive_lines()``: the one driving-line rule: rear cut edge midpoint to front
  cut edge midpoint (the line the implement's centre follows);
* UTM and WGS84 views (WGS84 only through ``geo.crs``) and one GeoJSON writer
  (``geojson_bytes``).

Per-cell values that travel with the cells (a prescription version's rates and
flags) are columns too; ``with_rates`` copies the geometry by reference.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import shapely

from .crs import to_wgs84, utm_coords_to_lonlat


def cell_centres(polys: np.ndarray) -> np.ndarray:
    """(n, 2) centre of every cell polygon: its area centroid, or a point on its surface
    where the centroid falls outside it (an L-shaped or split cell). NaN for empty cells.

    One-ring polygons (nearly all cells) use the shoelace formula in numpy, grouped
    by vertex count; the rest use GEOS. The inside test is the same for both.
    """
    polys = np.asarray(polys, dtype=object)
    n = len(polys)
    out = np.full((n, 2), np.nan)
    if n == 0:
        return out
    empty = shapely.is_empty(polys)
    simple = (
        ~empty & (shapely.get_type_id(polys) == 3) & (shapely.get_num_interior_rings(polys) == 0)
    )
    nc = shapely.get_num_coordinates(polys)
    for k in np.unique(nc[simple]):
        rows = np.flatnonzero(simple & (nc == k))
        # one ring each: the polygon's coordinates are its ring's (no ring objects made)
        out[rows] = _ring_centroids(shapely.get_coordinates(polys[rows]).reshape(len(rows), k, 2))
    other = np.flatnonzero(~simple & ~empty)
    if len(other):
        out[other] = shapely.get_coordinates(shapely.centroid(polys[other]))
    todo = np.flatnonzero(~empty)
    outside = ~shapely.contains_xy(polys[todo], out[todo, 0], out[todo, 1])
    if outside.any():
        bad = todo[outside]
        # on the boundary counts as inside (a degenerate sliver's centroid)
        on_edge = shapely.intersects_xy(polys[bad], out[bad, 0], out[bad, 1])
        bad = bad[~on_edge]
        if len(bad):
            out[bad] = shapely.get_coordinates(shapely.point_on_surface(polys[bad]))
    return out


def _ring_centroids(xy: np.ndarray) -> np.ndarray:
    """Area centroids of closed rings (m, k, 2) by the shoelace formula, on coordinates
    relative to each ring's first vertex (UTM magnitudes would cost digits); the vertex
    mean for a ring without area."""
    o = xy[:, :1, :]
    r = xy - o
    x0, y0 = r[:, :-1, 0], r[:, :-1, 1]
    x1, y1 = r[:, 1:, 0], r[:, 1:, 1]
    cr = x0 * y1 - x1 * y0
    a = cr.sum(axis=1) / 2.0
    flat = np.abs(a) <= 1e-12
    safe = np.where(flat, 1.0, a)
    c = np.stack([((x0 + x1) * cr).sum(axis=1), ((y0 + y1) * cr).sum(axis=1)], axis=1)
    c = c / (6.0 * safe)[:, None] + o[:, 0, :]
    if flat.any():
        c[flat] = xy[flat, :-1].mean(axis=1)
    return np.asarray(c)


def cut_edge_midpoints(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rear, front) midpoints of the cut edges of (n, 4, 2) corners (rear-right,
    front-right, front-left, rear-left): the ends of each cell's driving line."""
    c = np.asarray(corners, dtype=float).reshape(-1, 4, 2)
    return (c[:, 3] + c[:, 0]) / 2.0, (c[:, 1] + c[:, 2]) / 2.0


def rectangles(corners: np.ndarray) -> np.ndarray:
    """(n, 4, 2) corners -> shapely Polygons (ragged-array path, ~2x faster than polygons())."""
    c = np.asarray(corners, dtype=float).reshape(-1, 4, 2)
    n = len(c)
    if n == 0:
        return np.zeros(0, dtype=object)
    closed = np.concatenate([c, c[:, :1]], axis=1).reshape(-1, 2)
    offsets = (np.arange(0, 5 * n + 1, 5), np.arange(n + 1))
    return np.asarray(shapely.from_ragged_array(shapely.GeometryType.POLYGON, closed, offsets))


def round_coords(geoms: Any, decimals: int) -> Any:
    """Round every coordinate pointwise (no overlay, unlike GEOS ``set_precision``'s
    snapping, so it cannot raise a TopologyException). At 9 decimals of a degree
    (0.1 mm) or 3 of a metre this cannot make a cell-sized polygon invalid."""
    return shapely.transform(geoms, lambda c: np.round(c, decimals))


def round_valid(geoms: Any, decimals: int) -> Any:
    """``round_coords``, then every polygon rounding made invalid (a pinched clipped cell:
    two vertices 0.1 mm apart become one, a spike or a self-touching ring) snapped to the
    same grid by GEOS with a valid result, so what a file writes is valid as written
    (OGC simple features: rings that do not self-intersect). Pointwise rounding stays the
    rule for the rest (fast, and no overlay that could raise); a snap that still raises is
    repaired with ``make_valid`` on the rounded coordinates and rounded again."""
    out = np.asarray(round_coords(geoms, decimals), dtype=object)
    scalar = out.ndim == 0
    out = out.reshape(-1)
    src = np.asarray(geoms, dtype=object).reshape(-1)
    bad = np.flatnonzero(~shapely.is_valid(out) & ~shapely.is_missing(out))
    grid = 10.0**-decimals
    for i in bad:
        try:
            g = shapely.set_precision(src[i], grid, mode="valid_output")
        except shapely.errors.GEOSException:
            g = shapely.set_precision(shapely.make_valid(out[i]), grid, mode="valid_output")
        out[i] = g
    return out[0] if scalar else out


# one value per cell: a list or a numpy array
Column = Sequence[Any] | np.ndarray

GEOJSON_DECIMALS = 9  # ~0.1 mm in degrees; RFC 7946 recommends no more than needed


def _json_texts(name: str, col: Column) -> list[str]:
    """``"name":value`` JSON text for every value of one property column (non-finite
    floats become null: RFC 8259 has no NaN)."""
    key = json.dumps(name) + ":"
    a = col if isinstance(col, np.ndarray) else np.zeros(0, dtype=object)
    if a.dtype.kind in "iu":
        return [key + v for v in map(str, a.tolist())]
    if a.dtype.kind == "b":
        return [key + ("true" if v else "false") for v in a.tolist()]
    if a.dtype.kind == "f":
        ok = np.isfinite(a)
        vals = zip(a.tolist(), ok.tolist(), strict=True)
        return [key + (repr(v) if f else "null") for v, f in vals]
    cache: dict[Any, str] = {}
    out = []
    for v in a.tolist() if len(a) else col:
        k = (type(v), v if isinstance(v, str | int | float | None) else json.dumps(v))
        t = cache.get(k)
        if t is None:
            t = cache[k] = key + json.dumps(v, separators=(",", ":"))
        out.append(t)
    return out


@dataclass(eq=False)
class Cells:
    """Cells in path order; every column has one row per cell (see module docstring).

    ``epsg`` is the field's UTM zone (0 when unknown: the WGS84 views refuse).
    ``headland``, ``rate_kg_ha`` and ``flags`` default to False / 0.
    ``cell_length_m``, ``swath_width_m``, ``uncovered_m2`` and ``timings_s`` are the
    grid builder's (NaN / 0 / empty for cells read back from the store).
    """

    epsg: int
    seq: np.ndarray
    swath: np.ndarray
    index_in_swath: np.ndarray
    corners_utm: np.ndarray
    area_m2: np.ndarray
    polygons_utm: np.ndarray
    headland: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    rate_kg_ha: np.ndarray = field(default_factory=lambda: np.zeros(0))
    flags: np.ndarray = field(default_factory=lambda: np.zeros(0, np.uint16))
    cell_length_m: float = float("nan")
    swath_width_m: float = float("nan")
    # field area no cell covers (thin peninsulas the headland offsets cannot reach,
    # wedges where a swath stops at a hole or notch): reported, never hidden
    uncovered_m2: float = 0.0
    timings_s: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = len(self.seq)
        self.epsg = int(self.epsg)
        self.seq = np.asarray(self.seq, dtype=np.int64)
        self.swath = np.asarray(self.swath, dtype=np.int64)
        self.index_in_swath = np.asarray(self.index_in_swath, dtype=np.int64)
        self.corners_utm = np.asarray(self.corners_utm, dtype=float).reshape(n, 4, 2)
        self.area_m2 = np.asarray(self.area_m2, dtype=float)
        self.polygons_utm = np.asarray(self.polygons_utm, dtype=object)
        self.headland = np.asarray(self.headland if len(self.headland) else np.zeros(n), bool)
        rate = self.rate_kg_ha if len(self.rate_kg_ha) else np.zeros(n)
        self.rate_kg_ha = np.asarray(rate, dtype=float)
        flags = self.flags if len(self.flags) else np.zeros(n)
        self.flags = np.asarray(flags, dtype=np.uint16)
        for name in (
            "swath", "index_in_swath", "area_m2", "polygons_utm", "headland", "rate_kg_ha",
            "flags",
        ):  # fmt: skip
            if len(getattr(self, name)) != n:
                raise ValueError(f"Cells: {name} has {len(getattr(self, name))} rows, expected {n}")
        self._views: dict[str, np.ndarray] = {}

    def __len__(self) -> int:
        return len(self.seq)

    # views ---------------------------------------------------------------------------

    def _need_epsg(self) -> int:
        if self.epsg <= 0:
            raise ValueError("Cells: no UTM zone (epsg) known, so no WGS84 view")
        return self.epsg

    @property
    def centroids_utm(self) -> np.ndarray:
        """(n, 2) cell centres by the one rule (``cell_centres``), computed once."""
        c = self._views.get("centroids_utm")
        if c is None:
            c = self._views["centroids_utm"] = cell_centres(self.polygons_utm)
        return c

    @property
    def corners_wgs84(self) -> np.ndarray:
        """(n, 4, 2) lon/lat corners, same order as ``corners_utm`` (seed 001 Table 1)."""
        c = self._views.get("corners_wgs84")
        if c is None:
            c = self._views["corners_wgs84"] = utm_coords_to_lonlat(
                self.corners_utm, self._need_epsg()
            )
        return c

    def polygons_wgs84(self) -> np.ndarray:
        """The real cells in lon/lat (computed once, or adopted from the store)."""
        p = self._views.get("polygons_wgs84")
        if p is None:
            p = self._views["polygons_wgs84"] = to_wgs84(self.polygons_utm, self._need_epsg())
        return p

    def adopt_views(self, **views: np.ndarray) -> None:
        """Keep views the caller already computed (the store reads lon/lat polygons):
        ``polygons_wgs84`` and/or ``centroids_utm``; each must have n rows."""
        for name, v in views.items():
            if name not in ("polygons_wgs84", "centroids_utm", "corners_wgs84"):
                raise ValueError(f"Cells: no view {name!r}")
            if len(v) != len(self):
                raise ValueError(f"Cells: {len(v)} rows of {name} for {len(self)} cells")
            self._views[name] = v

    @property
    def total_area_m2(self) -> float:
        return float(self.area_m2.sum())

    # derived tables ------------------------------------------------------------------

    def with_rates(self, rate_kg_ha: np.ndarray, flags: np.ndarray | None = None) -> Cells:
        """A copy sharing the geometry with new rates (and flags): versions never alias."""
        out = replace(
            self,
            rate_kg_ha=np.array(rate_kg_ha, dtype=float),
            flags=np.array(self.flags if flags is None else flags, dtype=np.uint16),
        )
        out._views = dict(self._views)
        return out

    def take(self, rows: np.ndarray) -> Cells:
        """The cells at ``rows`` (indexes or a mask), views carried along."""
        out = replace(
            self,
            seq=self.seq[rows],
            swath=self.swath[rows],
            index_in_swath=self.index_in_swath[rows],
            corners_utm=self.corners_utm[rows],
            area_m2=self.area_m2[rows],
            polygons_utm=self.polygons_utm[rows],
            headland=self.headland[rows],
            rate_kg_ha=self.rate_kg_ha[rows],
            flags=self.flags[rows],
            timings_s=dict(self.timings_s),
        )
        out._views = {k: v[rows] for k, v in self._views.items()}
        return out

    # GeoJSON -------------------------------------------------------------------------

    def geojson_features(
        self, columns: Mapping[str, Column], decimals: int = GEOJSON_DECIMALS
    ) -> list[str]:
        """One RFC 7946 Feature (compact JSON text) per cell, lon/lat, path order.

        ``columns``: property name -> one value per cell, written in that order. Built
        from shapely's vectorised ``to_geojson`` strings instead of parsing and
        re-serialising every geometry (5x faster on 100k cells).
        """
        n = len(self)
        for name, col in columns.items():
            if len(col) != n:
                raise ValueError(f"GeoJSON: column {name} has {len(col)} rows for {n} cells")
        geoms = shapely.to_geojson(round_valid(self.polygons_wgs84(), decimals))
        texts = [_json_texts(k, c) for k, c in columns.items()]
        props = [",".join(row) for row in zip(*texts, strict=True)] if texts else [""] * n
        return [
            f'{{"type":"Feature","id":{q},"geometry":{g},"properties":{{{p}}}}}'
            for q, g, p in zip(self.seq.tolist(), geoms.tolist(), props, strict=True)
        ]

    def geojson_bytes(
        self,
        columns: Mapping[str, Column],
        properties: Mapping[str, Any] | None = None,
        decimals: int = GEOJSON_DECIMALS,
    ) -> bytes:
        """A FeatureCollection of ``geojson_features``; ``properties`` (e.g. prescription
        id and version) go on the collection as a foreign member readers ignore."""
        head = '{"type":"FeatureCollection",'
        if properties:
            head += '"properties":' + json.dumps(properties, separators=(",", ":")) + ","
        feats = self.geojson_features(columns, decimals)
        return (head + '"features":[' + ",".join(feats) + "]}").encode()

    def to_geojson(self, rates_kg_ha: np.ndarray | None = None) -> dict[str, Any]:
        """The grid as a FeatureCollection dict: seq, swath, index_in_swath, area, headland
        (and a rate per cell when given)."""
        cols: dict[str, Column] = {
            "seq": self.seq,
            "swath": self.swath,
            "index_in_swath": self.index_in_swath,
            "area_m2": np.round(self.area_m2, 3),
            "headland": self.headland,
        }
        if rates_kg_ha is not None:
            cols["rate_kg_ha"] = np.asarray(rates_kg_ha, dtype=float)
        out: dict[str, Any] = json.loads(self.geojson_bytes(cols))
        return out

    # constructors --------------------------------------------------------------------

    @classmethod
    def empty(cls, epsg: int) -> Cells:
        return cls(
            epsg=epsg,
            seq=np.zeros(0, np.int64),
            swath=np.zeros(0, np.int64),
            index_in_swath=np.zeros(0, np.int64),
            corners_utm=np.zeros((0, 4, 2)),
            area_m2=np.zeros(0),
            polygons_utm=np.zeros(0, dtype=object),
        )

    @classmethod
    def from_polygons_utm(
        cls,
        epsg: int,
        seq: np.ndarray,
        swath: np.ndarray,
        polygons_utm: np.ndarray,
        corners_utm: np.ndarray | None = None,
    ) -> Cells:
        """From real UTM polygons; corners default to each polygon's oriented minimum
        rectangle (exact for uncut cells), counter-clockwise."""
        polys = np.asarray(polygons_utm, dtype=object)
        n = len(polys)
        if corners_utm is None:
            corners_utm = _oriented_corners(polys)
        sw = np.asarray(swath, dtype=np.int64)
        return cls(
            epsg=epsg,
            seq=np.asarray(seq),
            swath=sw,
            index_in_swath=index_in_swath(sw),
            corners_utm=np.asarray(corners_utm, dtype=float).reshape(n, 4, 2),
            area_m2=shapely.area(polys) if n else np.zeros(0),
            polygons_utm=polys,
        )

    @classmethod
    def rectangle(
        cls,
        epsg: int,
        x0: float,
        y0: float,
        n_swaths: int,
        n_per_swath: int,
        width_m: float = 2.3,
        length_m: float = 5.0,
        clip: Any = None,
    ) -> Cells:
        """A boustrophedon grid of north-running swaths starting at (x0, y0) in UTM.

        For tests and benchmarks besides ``geo.grid``: swath s runs north when s is
        even and south when odd; cells are numbered 0.. along the path. ``clip``
        (UTM polygon) clips cells and drops empty ones.
        """
        s = np.repeat(np.arange(n_swaths), n_per_swath)
        k = np.tile(np.arange(n_per_swath), n_swaths)
        k_geo = np.where(s % 2 == 0, k, n_per_swath - 1 - k)
        xmin = x0 + s * width_m
        ymin = y0 + k_geo * length_m
        xmax, ymax = xmin + width_m, ymin + length_m
        north = (s % 2 == 0)[:, None]
        c_north = np.stack(
            [np.column_stack(p) for p in ((xmax, ymin), (xmax, ymax), (xmin, ymax), (xmin, ymin))],
            axis=1,
        )
        c_south = np.stack(
            [np.column_stack(p) for p in ((xmin, ymax), (xmin, ymin), (xmax, ymin), (xmax, ymax))],
            axis=1,
        )
        corners = np.where(north[:, :, None], c_north, c_south)
        polys = shapely.box(xmin, ymin, xmax, ymax)
        keep = np.ones(len(polys), dtype=bool)
        if clip is not None:
            polys = polygonal_parts(shapely.intersection(polys, clip))
            keep = shapely.area(polys) > 1e-6
        polys, corners, s = polys[keep], corners[keep], s[keep]
        return cls.from_polygons_utm(epsg, np.arange(int(keep.sum())), s, polys, corners)


def index_in_swath(swath: np.ndarray) -> np.ndarray:
    """0.. index of each cell within its run of equal swath numbers (path order)."""
    sw = np.asarray(swath)
    n = len(sw)
    if n == 0:
        return np.zeros(0, np.int64)
    start = np.r_[True, sw[1:] != sw[:-1]]
    first = np.maximum.accumulate(np.where(start, np.arange(n), 0))
    return (np.arange(n) - first).astype(np.int64)


def polygonal_parts(geoms: np.ndarray) -> np.ndarray:
    """Overlay results as (Multi)Polygons: lines and points where a cell only touches
    the clip are dropped; a cell split in parts stays whole (MultiPolygon)."""
    geoms = np.asarray(geoms, dtype=object).copy()
    tid = shapely.get_type_id(geoms)
    for i in np.flatnonzero((tid != 3) & (tid != 6)):
        parts = [g for g in shapely.get_parts(geoms[i]) if shapely.get_type_id(g) in (3, 6)]
        geoms[i] = shapely.union_all(parts) if parts else shapely.Polygon()
    return geoms


def _oriented_corners(polys: np.ndarray) -> np.ndarray:
    n = len(polys)
    rects = shapely.orient_polygons(shapely.oriented_envelope(polys), exterior_cw=False)
    rings = shapely.get_exterior_ring(rects)
    if n and (shapely.get_num_coordinates(rings) == 5).all():  # the usual case
        return np.asarray(shapely.get_coordinates(rings).reshape(n, 5, 2)[:, :4])
    corners = np.zeros((n, 4, 2))
    for i, r in enumerate(rects):
        if r.geom_type == "Polygon":
            b = np.asarray(r.exterior.coords)
        else:  # degenerate sliver: a line or point, repeat its points
            b = np.asarray(r.coords)
        corners[i] = np.resize(b[:4] if len(b) >= 4 else b, (4, 2))
    return corners
