"""Path-ordered prescription cells as column arrays.

``CellTable`` is the one in-memory shape that rate models, interpolation and
every export work on: the grid of seed 001 sec. 1.2 (cells in path order, four
counter-clockwise corners each, Table 1) plus the field's clipped cell
polygons. Arrays, not objects per cell, so 100k-cell grids stay vectorised.

It can be built from ``fieldrx.geo.grid.Grid`` (``from_grid``), from stored
rows (``from_polygons_wgs84``), or as a plain rectangular test grid
(``rectangle``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import shapely
from pyproj import Transformer

# Per-cell flags are a bit mask so that they stay one uint16 column; names are
# what the API, tiles and exports show.
FLAG_BITS: dict[str, int] = {
    "no_data": 1,  # interpolation had no sample for the cell: fallback rate used
    "below_meter_range": 2,  # rate raised to the lowest meterable rate
    "above_meter_range": 4,  # rate lowered to the highest meterable rate
    "manual": 8,  # rate set by a per-cell edit
    "zone": 16,  # rate set by zone painting
}


def flag_names(mask: int) -> list[str]:
    """Names of the flags set in one cell's mask, in FLAG_BITS order."""
    return [name for name, bit in FLAG_BITS.items() if int(mask) & bit]


def flag_strings(flags: np.ndarray) -> list[str]:
    """Comma-separated flag names per cell ("" when none), for tables and tiles."""
    cache: dict[int, str] = {}
    out: list[str] = []
    for m in np.asarray(flags, dtype=np.int64).tolist():
        s = cache.get(m)
        if s is None:
            s = cache[m] = ",".join(flag_names(m))
        out.append(s)
    return out


def _transformer(src_epsg: int, dst_epsg: int) -> Transformer:
    return Transformer.from_crs(src_epsg, dst_epsg, always_xy=True)


def transform_geoms(geoms: Any, src_epsg: int, dst_epsg: int) -> Any:
    """Reproject shapely geometries (scalar or array) with pyproj, lon/lat order."""
    tr = _transformer(src_epsg, dst_epsg)

    def fn(coords: np.ndarray) -> np.ndarray:
        x, y = tr.transform(coords[:, 0], coords[:, 1])
        return np.column_stack([x, y])

    return shapely.transform(geoms, fn)


def round_coords(geoms: Any, decimals: int) -> Any:
    """Round every coordinate (fast, unlike GEOS ``set_precision``'s snapping overlay).

    At 9 decimals of a degree (0.1 mm) or 3 of a metre this cannot make a
    cell-sized polygon invalid.
    """
    return shapely.transform(geoms, lambda c: np.round(c, decimals))


def transform_xy(
    x: np.ndarray, y: np.ndarray, src_epsg: int, dst_epsg: int
) -> tuple[np.ndarray, np.ndarray]:
    """Reproject coordinate arrays (always x/lon first)."""
    tx, ty = _transformer(src_epsg, dst_epsg).transform(np.asarray(x), np.asarray(y))
    return np.asarray(tx, dtype=float), np.asarray(ty, dtype=float)


@dataclass
class CellTable:
    """Cells in path order. All arrays have length n (corners: n x 4 x 2).

    ``corners_*`` are the uncut rectangles of seed 001 (counter-clockwise, the
    job package and Table 1 use them); ``polygons_utm`` are the cells clipped to
    the field (area, exports and interpolation use them). WGS84 coordinates are
    lon/lat (x, y) everywhere in arrays; only the Table 1 CSV writes lat first.
    """

    epsg: int
    seq: np.ndarray
    swath: np.ndarray
    polygons_utm: np.ndarray
    centroids_utm: np.ndarray
    corners_utm: np.ndarray
    corners_wgs84: np.ndarray
    area_m2: np.ndarray
    rate_kg_ha: np.ndarray = field(default_factory=lambda: np.zeros(0))
    flags: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.uint16))

    def __post_init__(self) -> None:
        n = len(self.seq)
        self.seq = np.asarray(self.seq, dtype=np.int64)
        self.swath = np.asarray(self.swath, dtype=np.int64)
        self.polygons_utm = np.asarray(self.polygons_utm, dtype=object)
        self.centroids_utm = np.asarray(self.centroids_utm, dtype=float).reshape(n, 2)
        self.corners_utm = np.asarray(self.corners_utm, dtype=float).reshape(n, 4, 2)
        self.corners_wgs84 = np.asarray(self.corners_wgs84, dtype=float).reshape(n, 4, 2)
        self.area_m2 = np.asarray(self.area_m2, dtype=float)
        if len(self.rate_kg_ha) == 0:
            self.rate_kg_ha = np.zeros(n)
        if len(self.flags) == 0:
            self.flags = np.zeros(n, dtype=np.uint16)
        self.rate_kg_ha = np.asarray(self.rate_kg_ha, dtype=float)
        self.flags = np.asarray(self.flags, dtype=np.uint16)
        for name in ("swath", "polygons_utm", "area_m2", "rate_kg_ha", "flags"):
            if len(getattr(self, name)) != n:
                raise ValueError(
                    f"CellTable: {name} has {len(getattr(self, name))} rows, expected {n}"
                )
        self._wgs84_polys: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.seq)

    def with_rates(self, rate_kg_ha: np.ndarray, flags: np.ndarray | None = None) -> CellTable:
        """A copy sharing the geometry with new rates (and flags): versions never alias."""
        out = replace(
            self,
            rate_kg_ha=np.array(rate_kg_ha, dtype=float),
            flags=np.array(self.flags if flags is None else flags, dtype=np.uint16),
        )
        out._wgs84_polys = self._wgs84_polys
        return out

    def set_polygons_wgs84(self, polys: np.ndarray) -> None:
        """Adopt lon/lat polygons the caller already has (the planner), saving a transform."""
        if len(polys) != len(self.seq):
            raise ValueError(f"CellTable: {len(polys)} lon/lat polygons for {len(self.seq)} cells")
        self._wgs84_polys = np.asarray(polys, dtype=object)

    def polygons_wgs84(self) -> np.ndarray:
        """Clipped cell polygons in lon/lat (computed once)."""
        if self._wgs84_polys is None:
            self._wgs84_polys = transform_geoms(self.polygons_utm, self.epsg, 4326)
        return self._wgs84_polys

    @property
    def total_area_m2(self) -> float:
        return float(self.area_m2.sum())

    # constructors -----------------------------------------------------------

    @classmethod
    def from_grid(cls, grid: Any, epsg: int) -> CellTable:
        """From ``fieldrx.geo.grid.Grid`` (arrays already in path order)."""
        corners_wgs84 = grid.corners_wgs84(epsg)
        return cls(
            epsg=int(epsg),
            seq=np.asarray(grid.seq),
            swath=np.asarray(grid.swath),
            polygons_utm=np.asarray(grid.polygons),
            centroids_utm=np.asarray(grid.centroids_utm),
            corners_utm=np.asarray(grid.corners_utm),
            corners_wgs84=np.asarray(corners_wgs84),
            area_m2=np.asarray(grid.area_m2),
        )

    @classmethod
    def from_polygons_utm(
        cls,
        epsg: int,
        seq: np.ndarray,
        swath: np.ndarray,
        polygons_utm: np.ndarray,
        corners_utm: np.ndarray | None = None,
    ) -> CellTable:
        """From clipped UTM polygons; corners default to each polygon's oriented
        minimum rectangle (exact for uncut cells), counter-clockwise."""
        polys = np.asarray(polygons_utm, dtype=object)
        n = len(polys)
        if corners_utm is None:
            rects = shapely.orient_polygons(shapely.oriented_envelope(polys), exterior_cw=False)
            rings = shapely.get_exterior_ring(rects)
            if n and (shapely.get_num_coordinates(rings) == 5).all():  # the usual case
                corners_utm = shapely.get_coordinates(rings).reshape(n, 5, 2)[:, :4]
            else:
                corners_utm = np.zeros((n, 4, 2))
                for i, r in enumerate(rects):
                    if r.geom_type == "Polygon":
                        b = np.asarray(r.exterior.coords)
                    else:  # degenerate sliver: a line or point, repeat its points
                        b = np.asarray(r.coords)
                    corners_utm[i] = np.resize(b[:4] if len(b) >= 4 else b, (4, 2))
        corners_utm = np.asarray(corners_utm, dtype=float).reshape(n, 4, 2)
        cx, cy = transform_xy(corners_utm[..., 0].ravel(), corners_utm[..., 1].ravel(), epsg, 4326)
        cent = shapely.get_coordinates(shapely.centroid(polys)) if n else np.zeros((0, 2))
        return cls(
            epsg=int(epsg),
            seq=np.asarray(seq),
            swath=np.asarray(swath),
            polygons_utm=polys,
            centroids_utm=cent,
            corners_utm=corners_utm,
            corners_wgs84=np.column_stack([cx, cy]).reshape(n, 4, 2),
            area_m2=shapely.area(polys),
        )

    @classmethod
    def from_polygons_wgs84(
        cls,
        epsg: int,
        seq: np.ndarray,
        swath: np.ndarray,
        polygons_wgs84: np.ndarray,
        corners_wgs84: np.ndarray | None = None,
    ) -> CellTable:
        """From rows as stored in PostGIS (SRID 4326) with the field's UTM EPSG."""
        polys_utm = transform_geoms(np.asarray(polygons_wgs84, dtype=object), 4326, epsg)
        corners_utm = None
        if corners_wgs84 is not None:
            c = np.asarray(corners_wgs84, dtype=float).reshape(-1, 4, 2)
            x, y = transform_xy(c[..., 0].ravel(), c[..., 1].ravel(), 4326, epsg)
            corners_utm = np.column_stack([x, y]).reshape(-1, 4, 2)
        return cls.from_polygons_utm(epsg, seq, swath, polys_utm, corners_utm)

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
    ) -> CellTable:
        """A boustrophedon grid of north-running swaths starting at (x0, y0) in UTM.

        For tests and benchmarks until (and besides) ``fieldrx.geo.grid``:
        swath s runs north when s is even and south when odd; cells are numbered
        0.. along the path (like ``geo.grid``). ``clip`` (UTM polygon) clips cells
        and drops empty ones.
        """
        s = np.repeat(np.arange(n_swaths), n_per_swath)
        k = np.tile(np.arange(n_per_swath), n_swaths)
        k_geo = np.where(s % 2 == 0, k, n_per_swath - 1 - k)
        xmin = x0 + s * width_m
        ymin = y0 + k_geo * length_m
        xmax, ymax = xmin + width_m, ymin + length_m
        north = (s % 2 == 0)[:, None]
        # CCW like geo.grid: rear-right, front-right, front-left, rear-left
        c_north = np.stack(
            [
                np.column_stack([xmax, ymin]),
                np.column_stack([xmax, ymax]),
                np.column_stack([xmin, ymax]),
                np.column_stack([xmin, ymin]),
            ],
            axis=1,
        )
        c_south = np.stack(
            [
                np.column_stack([xmin, ymax]),
                np.column_stack([xmin, ymin]),
                np.column_stack([xmax, ymin]),
                np.column_stack([xmax, ymax]),
            ],
            axis=1,
        )
        corners = np.where(north[:, :, None], c_north, c_south)
        polys = shapely.box(xmin, ymin, xmax, ymax)
        keep = np.ones(len(polys), dtype=bool)
        if clip is not None:
            polys = shapely.intersection(polys, clip)
            polys = np.array(
                [
                    shapely.union_all(
                        [g for g in getattr(p, "geoms", [p]) if g.geom_type == "Polygon"]
                    )
                    if p.geom_type not in ("Polygon", "MultiPolygon")
                    else p
                    for p in polys
                ],
                dtype=object,
            )
            keep = shapely.area(polys) > 1e-6
        polys, corners, s = polys[keep], corners[keep], s[keep]
        n = int(keep.sum())
        table = cls.from_polygons_utm(epsg, np.arange(n), s, polys, corners)
        return table
