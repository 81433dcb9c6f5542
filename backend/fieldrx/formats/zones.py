"""Polygons that every reader accepts, and treatment zones dissolved by rate class.

Two mechanisms shared by the Shapefile and ISO 11783-10 writers:

* ``snap_valid``: coordinates are written with a fixed number of decimals
  (9 for degrees, the ISO XSD's limit). Rounding each vertex on its own can
  make a thin clipped cell self-intersect or collapse a ring (issue 19 found
  12..15 invalid cells per field). GEOS precision reduction
  (``shapely.set_precision``) snaps to the same grid *and* repairs the result,
  so the coordinates as written are valid; parts that collapse to nothing at
  that precision (< 0.1 mm wide) are dropped and counted.
* ``dissolve_zones``: one polygon per cell (17,401 on 20 ha) is far beyond
  what terminals accept (Climate FieldView documents at most 100 zones).
  Cells are grouped into ``n_classes`` equal-width rate classes (each class
  at the area-weighted mean rate of its cells);
  connected patches smaller than a minimum area are merged into the
  neighbouring class they share most cells with, and the minimum is doubled
  until the dissolved polygon count fits ``max_polygons``. What moved is
  reported (``ZoneSummary``): area reassigned and the largest rate change a
  cell saw, so the export says what it simplified.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from fieldrx.agronomy.cells import CellTable
from fieldrx.formats import FormatError
from fieldrx.geo.crs import to_wgs84

DEGREE_DECIMALS = 9
DEFAULT_ZONE_CLASSES = 8
MAX_ZONE_CLASSES = 254  # ISO 11783-10 TZN codes 1..254 (0 is "no rate")
DEFAULT_MAX_POLYGONS = 100  # Climate FieldView's documented zone limit, the tightest we know
MAX_SIEVE_ROUNDS = 64


def snap_valid(geoms: Any, decimals: int = DEGREE_DECIMALS) -> Any:
    """Polygons snapped to ``10**-decimals`` and valid in those coordinates (see module doc).

    Exterior rings come back counter-clockwise; writers orient as their format
    wants (``shapely.orient_polygons``). Empty results stay empty.
    """
    return shapely.set_precision(geoms, 10.0**-decimals, mode="valid_output")


def polygon_parts(geom: Any) -> list[Any]:
    """The non-empty Polygons of a Polygon / MultiPolygon / collection."""
    if geom is None or shapely.is_empty(geom):
        return []
    if geom.geom_type == "Polygon":
        return [geom]
    out: list[Any] = []
    for g in getattr(geom, "geoms", []):
        out.extend(polygon_parts(g))
    return out


@dataclass
class Zone:
    """One rate class: its setpoint and its dissolved WGS84 polygons (valid, snapped)."""

    rate_kg_ha: float
    polygons: list[Any]
    area_m2: float
    n_cells: int


@dataclass
class ZoneSummary:
    n_cells: int
    n_classes_requested: int
    n_zones: int
    n_polygons: int
    max_polygons: int
    min_patch_m2: float
    area_reassigned_m2: float
    max_rate_change_kg_ha: float
    area_weighted_rate_error_kg_ha: float

    def to_dict(self) -> dict[str, Any]:
        return {k: (round(v, 3) if isinstance(v, float) else v) for k, v in asdict(self).items()}

    def note(self) -> str:
        return (
            f"{self.n_cells} cells dissolved into {self.n_zones} rate zones "
            f"({self.n_polygons} polygons, limit {self.max_polygons}); "
            f"{self.area_reassigned_m2:.0f} m2 in patches under {self.min_patch_m2:.0f} m2 "
            f"joined a neighbouring zone; largest cell rate change "
            f"{self.max_rate_change_kg_ha:.2f} kg/ha"
        )


def _classes(rate: np.ndarray, n_classes: int) -> np.ndarray:
    """Class index per cell: one per distinct rate (0.01 kg/ha) or equal-width classes."""
    cents = np.rint(np.asarray(rate, dtype=float) * 100.0).astype(np.int64)
    uniq, inv = np.unique(cents, return_inverse=True)
    if len(uniq) <= n_classes:
        return inv.ravel()
    lo, hi = float(cents.min()), float(cents.max())
    k = np.minimum(((cents - lo) / (hi - lo) * n_classes).astype(np.int64), n_classes - 1)
    return np.unique(k, return_inverse=True)[1].ravel()


def _adjacency(polys_utm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (i < j) of cells sharing a piece of edge at least 1 cm long.

    Neighbouring cells' shared edges carry floating-point noise (gaps or
    overlaps of nanometres), so cells within 1 mm count, and a 1 mm buffer's
    overlap area tells an edge (>= 1 cm x 1 mm) from a shared corner.
    """
    tree = shapely.STRtree(polys_utm)
    a, b = tree.query(polys_utm, predicate="dwithin", distance=1e-3)
    keep = a < b
    a, b = a[keep], b[keep]
    if len(a):
        inter = shapely.intersection(shapely.buffer(polys_utm[a], 1e-3, quad_segs=1), polys_utm[b])
        edge = shapely.area(inter) > 1e-5
        a, b = a[edge], b[edge]
    return a, b


def _patches(cls: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected same-class patches: (count, patch index per cell)."""
    n = len(cls)
    same = cls[a] == cls[b]
    g = coo_matrix((np.ones(int(same.sum())), (a[same], b[same])), shape=(n, n))
    k, comp = connected_components(g, directed=False)
    return int(k), comp


def _sieve(
    cls: np.ndarray, area: np.ndarray, a: np.ndarray, b: np.ndarray, min_patch: float
) -> np.ndarray:
    """Merge connected same-class patches smaller than ``min_patch`` m^2 into a neighbour.

    Each round every small patch joins the class of the neighbouring patch it
    shares most cell edges with among the neighbours *larger* than itself
    (area, then index, breaks ties), so merges form a forest and never swap
    back and forth; patches grow every round until none is small.
    """
    cls = cls.copy()
    for _ in range(MAX_SIEVE_ROUNDS):
        _, comp = _patches(cls, a, b)
        comp_area = np.bincount(comp, weights=area)
        small = comp_area < min_patch
        if not small.any():
            break
        pa, pb = comp[a], comp[b]
        cross = pa != pb
        src = np.concatenate([pa[cross], pb[cross]])
        dst = np.concatenate([pb[cross], pa[cross]])
        bigger = (comp_area[dst] > comp_area[src]) | (
            (comp_area[dst] == comp_area[src]) & (dst > src)
        )
        keep = small[src] & bigger
        if not keep.any():
            break
        src, dst = src[keep], dst[keep]
        m = len(comp_area)
        pair, votes = np.unique(src.astype(np.int64) * m + dst, return_counts=True)
        ps, pd = pair // m, pair % m
        order = np.lexsort((-votes, ps))  # per source patch, most shared edges first
        ps, pd = ps[order], pd[order]
        first = np.ones(len(ps), dtype=bool)
        first[1:] = ps[1:] != ps[:-1]
        target_cls = np.arange(m)  # patch -> new class (default: keep)
        patch_cls = np.zeros(m, dtype=cls.dtype)
        patch_cls[comp] = cls
        target_cls = patch_cls.copy()
        target_cls[ps[first]] = patch_cls[pd[first]]
        cls = target_cls[comp]
    return cls


def _dissolve(cells: CellTable, cls: np.ndarray, decimals: int) -> list[tuple[int, Any]]:
    """Union per class in UTM (fast), then to lon/lat and ``snap_valid`` (slivers < 0.1 mm go)."""
    out = []
    for c in np.unique(cls).tolist():
        merged = shapely.union_all(cells.polygons_utm[cls == c])
        wgs = to_wgs84(merged, cells.epsg)
        out.append((int(c), snap_valid(wgs, decimals)))
    return out


def dissolve_zones(
    cells: CellTable,
    n_classes: int = DEFAULT_ZONE_CLASSES,
    max_polygons: int = DEFAULT_MAX_POLYGONS,
    min_patch_m2: float | None = None,
    decimals: int = DEGREE_DECIMALS,
) -> tuple[list[Zone], ZoneSummary]:
    """Rate-class zones of the prescription (see module docstring), highest rate last."""
    if len(cells) == 0:
        raise FormatError("prescription has no cells")
    if not 1 <= n_classes <= MAX_ZONE_CLASSES:
        raise FormatError(f"zone classes must be in 1..{MAX_ZONE_CLASSES}, got {n_classes}")
    if max_polygons < n_classes:
        raise FormatError(
            f"max polygons ({max_polygons}) must be at least the zone classes ({n_classes})"
        )
    rate = cells.rate_kg_ha
    area = cells.area_m2
    cls0 = _classes(rate, n_classes)
    a, b = _adjacency(cells.polygons_utm)
    min_patch = float(np.median(area) * 4.0) if min_patch_m2 is None else float(min_patch_m2)
    while True:
        cls = _sieve(cls0, area, a, b, min_patch) if min_patch > 0 else cls0
        n_patches, _ = _patches(cls, a, b)
        if n_patches <= max_polygons or min_patch > cells.total_area_m2:
            break
        min_patch = max(min_patch * 2.0, float(np.median(area)))
    merged = _dissolve(cells, cls, decimals)
    n_poly = sum(len(polygon_parts(g)) for _, g in merged)
    if n_poly > max_polygons:
        raise FormatError(
            f"the zones need {n_poly} polygons, more than the limit {max_polygons}: "
            "use fewer zone classes"
        )
    w = area + 1e-12
    zone_rate = {
        c: float(np.sum(w[cls == c] * rate[cls == c]) / np.sum(w[cls == c]))
        for c in np.unique(cls).tolist()
    }
    zones = []
    for c, geom in sorted(merged, key=lambda cg: zone_rate[cg[0]]):
        zones.append(
            Zone(
                rate_kg_ha=round(zone_rate[c], 2),
                polygons=polygon_parts(geom),
                area_m2=float(area[cls == c].sum()),
                n_cells=int((cls == c).sum()),
            )
        )
    new_rate = np.asarray([round(zone_rate[c], 2) for c in cls.tolist()])
    change = np.abs(new_rate - rate)
    summary = ZoneSummary(
        n_cells=len(cells),
        n_classes_requested=n_classes,
        n_zones=len(zones),
        n_polygons=n_poly,
        max_polygons=max_polygons,
        min_patch_m2=min_patch,
        area_reassigned_m2=float(area[cls != cls0].sum()),
        max_rate_change_kg_ha=float(change.max(initial=0.0)),
        area_weighted_rate_error_kg_ha=float(np.sum(change * area) / max(area.sum(), 1e-12)),
    )
    return zones, summary
