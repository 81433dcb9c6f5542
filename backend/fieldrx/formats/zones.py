"""Polygons that every reader accepts, and treatment zones dissolved by rate class.

Two mechanisms shared by the Shapefile and ISO 11783-10 writers:

* ``snap_valid``: coordinates are written with a fixed number of decimals
  (9 for degrees, the ISO XSD's limit). Rounding each vertex on its own can
  make a thin clipped cell self-intersect or collapse a ring (found
  12..15 invalid cells per field). GEOS precision reduction
  (``shapely.set_precision``) snaps to the same grid *and* repairs the result,
  so the coordinates as written are valid; parts that collapse to nothing at
  that precision (< 0.1 mm wide) are dropped and counted.
* ``dissolve_zones``: one polygon per cell (17,401 on 20 ha) is far beyond
  what terminals accept (Climate FieldView documents at most 100 zones).
  Cells are grouped into ``n_classes`` equal-width rate classes (each class
  at the area-weighted mean rate of its cells). Each connected same-class
  patch dissolves into one polygon, so while there are more patches than
  ``max_polygons`` the smallest patch joins its most similar neighbour
  (closest class rate), and merging stops as soon as the count fits
  (``_sieve``: one priority queue over the patch adjacency, union-find; cell
  adjacency from a numpy edge-overlap test, ``_adjacency``). A cap that
  allows every class keeps every class, and only the smallest patches move.
  What moved is reported (``ZoneSummary``): area reassigned, patches merged
  and the largest rate change a moved cell saw, so the export says what it
  simplified. On the 500 ha bench field at 2.3 m x 5 m (436k cells) the old
  sieve (minimum patch area doubled until the count fit, full recomputation
  per round) took 365..382 s and left 2 zones, moving 79 % of the field; now
  15..35 s and 8 zones (``bench/zones.py`` has the figures). How much must
  move is set by the pattern: 734 patches into 100 polygons moved 69 % there.
"""

from __future__ import annotations

import heapq
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
_TOUCH_M = 1e-3  # cells' shared edges agree to within 1 mm (float noise is nanometres)
_EDGE_M = 1e-2  # at least 1 cm of shared edge is an edge, less is a corner
_PAIR_CHUNK = 100_000  # candidate cell pairs per numpy batch (~2M edge pairs)


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
    """One rate class: its setpoint and its dissolved WGS84 polygons (valid, snapped).

    The setpoint is the area-weighted mean rate of the cells binned into the
    class; cells merged in from smaller patches take it (``ZoneSummary``).
    """

    rate_kg_ha: float
    polygons: list[Any]
    area_m2: float
    n_cells: int


@dataclass
class ZoneSummary:
    """How the cells were simplified into zones (the export's note and ``info["zones"]``).

    ``area_reassigned_m2`` and ``max_moved_rate_change_kg_ha`` are what the
    polygon cap cost: cells whose patch joined another class. The largest
    change over all cells (``max_rate_change_kg_ha``) also counts the class
    binning itself (a cell's rate vs its class's mean).
    """

    n_cells: int
    n_classes_requested: int
    n_classes: int  # rate classes the cells fell into (fewer when fewer distinct rates)
    n_zones: int  # classes left after merging
    n_patches: int  # connected same-class patches before merging
    n_polygons: int
    max_polygons: int
    min_patch_m2: float  # caller's floor: patches smaller than this were merged anyway
    patches_merged: int
    largest_merged_patch_m2: float
    area_reassigned_m2: float
    max_moved_rate_change_kg_ha: float
    max_rate_change_kg_ha: float
    area_weighted_rate_error_kg_ha: float

    def to_dict(self) -> dict[str, Any]:
        return {k: (round(v, 3) if isinstance(v, float) else v) for k, v in asdict(self).items()}

    def note(self) -> str:
        head = (
            f"{self.n_cells} cells dissolved into {self.n_zones} rate zones "
            f"({self.n_polygons} polygons, limit {self.max_polygons}); "
        )
        if self.patches_merged == 0:
            moved = "no patch was merged; "
        else:
            moved = (
                f"{self.area_reassigned_m2:.0f} m2 in {self.patches_merged} patches "
                f"(the largest {self.largest_merged_patch_m2:.0f} m2) joined a neighbouring "
                f"zone, changing a cell's rate by at most "
                f"{self.max_moved_rate_change_kg_ha:.2f} kg/ha; "
            )
        return head + moved + f"largest cell rate change {self.max_rate_change_kg_ha:.2f} kg/ha"


def _classes(rate: np.ndarray, n_classes: int) -> np.ndarray:
    """Class index per cell: one per distinct rate (0.01 kg/ha) or equal-width classes."""
    cents = np.rint(np.asarray(rate, dtype=float) * 100.0).astype(np.int64)
    uniq, inv = np.unique(cents, return_inverse=True)
    if len(uniq) <= n_classes:
        return inv.ravel()
    lo, hi = float(cents.min()), float(cents.max())
    k = np.minimum(((cents - lo) / (hi - lo) * n_classes).astype(np.int64), n_classes - 1)
    return np.unique(k, return_inverse=True)[1].ravel()


def _edges(polys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every ring edge of every cell: start points, end points, cell index (sorted by cell)."""
    parts, part_cell = shapely.get_parts(polys, return_index=True)
    rings, ring_part = shapely.get_rings(parts, return_index=True)
    xy, ring = shapely.get_coordinates(rings, return_index=True)
    same = ring[1:] == ring[:-1]
    return xy[:-1][same], xy[1:][same], part_cell[ring_part[ring[:-1][same]]]


def _adjacency(polys_utm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (i < j) of cells sharing at least 1 cm of edge.

    Neighbouring cells' shared edges carry floating-point noise (gaps or
    overlaps of nanometres) and T-junctions (swaths' cells are staggered), so
    the test is numeric, per pair of edges: the edge of ``j`` lies within
    1 mm of the line of the edge of ``i`` and their projections overlap; the
    overlaps of a pair of cells are summed, >= 1 cm is an edge, less a shared
    corner. Candidates are the pairs whose 1 mm-grown bounding boxes meet
    (STRtree). Pure numpy over the edge pairs: a GEOS buffer + intersection per
    pair took 36 s for 42k cells under load, this a few seconds for 436k.
    """
    n = len(polys_utm)
    bb = shapely.bounds(polys_utm)
    tree = shapely.STRtree(polys_utm)
    g = _TOUCH_M
    grown = shapely.box(bb[:, 0] - g, bb[:, 1] - g, bb[:, 2] + g, bb[:, 3] + g)
    a, b = tree.query(grown)
    keep = a < b
    a, b = a[keep], b[keep]
    p0, p1, ecell = _edges(polys_utm)
    origin = p0.mean(axis=0) if len(p0) else np.zeros(2)
    p0, p1 = p0 - origin, p1 - origin
    start = np.searchsorted(ecell, np.arange(n + 1))
    ne = np.diff(start)
    out = np.zeros(len(a), dtype=bool)
    d = p1 - p0
    ln = np.hypot(d[:, 0], d[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        u = d / ln[:, None]
    for lo in range(0, len(a), _PAIR_CHUNK):
        ca, cb = a[lo : lo + _PAIR_CHUNK], b[lo : lo + _PAIR_CHUNK]
        na, nb = ne[ca], ne[cb]
        cnt = na * nb
        pair = np.repeat(np.arange(len(ca)), cnt)
        k = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        ei = start[ca][pair] + k // nb[pair]
        ej = start[cb][pair] + k % nb[pair]
        ui = u[ei]
        q0 = p0[ej] - p0[ei]
        q1 = p1[ej] - p0[ei]
        off0 = np.abs(ui[:, 0] * q0[:, 1] - ui[:, 1] * q0[:, 0])
        off1 = np.abs(ui[:, 0] * q1[:, 1] - ui[:, 1] * q1[:, 0])
        t0 = ui[:, 0] * q0[:, 0] + ui[:, 1] * q0[:, 1]
        t1 = ui[:, 0] * q1[:, 0] + ui[:, 1] * q1[:, 1]
        ov = np.minimum(ln[ei], np.maximum(t0, t1)) - np.maximum(0.0, np.minimum(t0, t1))
        ok = (off0 <= _TOUCH_M) & (off1 <= _TOUCH_M) & (ov > 0)
        shared = np.bincount(pair[ok], weights=ov[ok], minlength=len(ca))
        out[lo : lo + _PAIR_CHUNK] = shared >= _EDGE_M
    return a[out], b[out]


def _patches(cls: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected same-class patches: (count, patch index per cell)."""
    n = len(cls)
    same = cls[a] == cls[b]
    g = coo_matrix((np.ones(int(same.sum())), (a[same], b[same])), shape=(n, n))
    k, comp = connected_components(g, directed=False)
    return int(k), comp


@dataclass
class _Sieved:
    cls: np.ndarray  # class per cell after merging
    n_patches: int  # connected same-class patches left (= polygons the dissolve makes)
    n_merged: int  # patches that joined a neighbouring class
    largest_merged_m2: float  # area of the largest of them


def _sieve(
    cls: np.ndarray,
    class_rate: np.ndarray,
    area: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    max_patches: int,
    min_patch: float = 0.0,
) -> _Sieved:
    """Merge the smallest patches into their most similar neighbour until at most ``max_patches``.

    Patches are the connected same-class components (``_patches``, one
    ``connected_components`` call); their adjacency (shared cell edges) is
    built once with numpy. Then a priority queue by area pops the smallest
    live patch and merges it into the neighbouring patch whose class rate is
    closest to its own (ties: most shared edges, then larger area); every
    other neighbour of that class joins too, as the merged cells now connect
    them. Union-find keeps patch -> surviving patch. The loop stops as soon
    as the count fits (and no patch is below ``min_patch`` m^2). A class's
    last patch is never merged away, so every class survives (the cap is at
    least the class count), and what moves is the smallest area that meets
    the cap this way (greedy, smallest first).
    The old sieve doubled a minimum patch area and recomputed everything
    per round; the last doubling swept most of the field into two zones.
    """
    k, comp = _patches(cls, a, b)
    parea = np.bincount(comp, weights=area, minlength=k)
    if k <= max_patches and (min_patch <= 0 or parea.min() >= min_patch):
        return _Sieved(cls, k, 0, 0.0)
    pcls = np.zeros(k, dtype=np.int64)
    pcls[comp] = cls
    pa, pb = comp[a], comp[b]
    cross = pa != pb
    lo, hi = np.minimum(pa[cross], pb[cross]), np.maximum(pa[cross], pb[cross])
    key, shared = np.unique(lo.astype(np.int64) * k + hi, return_counts=True)
    nbr: list[dict[int, int]] = [{} for _ in range(k)]
    for x, y, e in zip((key // k).tolist(), (key % k).tolist(), shared.tolist(), strict=True):
        nbr[x][y] = e
        nbr[y][x] = e
    prate = class_rate[pcls].tolist()
    pc = pcls.tolist()
    ar = parea.tolist()
    parent = list(range(k))
    live = np.bincount(pcls).tolist()  # live patches per class
    heap = [(ar[i], i) for i in range(k)]
    heapq.heapify(heap)
    count, merged, largest = k, 0, 0.0
    while heap:
        size, p = heapq.heappop(heap)
        if parent[p] != p or size != ar[p]:
            continue  # merged away or grown since queued
        if count <= max_patches and size >= min_patch:
            break
        near = nbr[p]
        if not near or live[pc[p]] == 1:
            continue  # a separate part of the field, or its class's last patch: it stays
        rp = prate[p]
        q = min(near, key=lambda r: (abs(prate[r] - rp), -near[r], -ar[r], r))
        group = [r for r in near if pc[r] == pc[q]]
        root = max(group, key=lambda r: len(nbr[r]))
        members = [p] + [r for r in group if r != root]
        gone = set(members)
        into = nbr[root]
        for m in members:
            parent[m] = root
            ar[root] += ar[m]
            for r, e in nbr[m].items():
                if r == root or r in gone:
                    continue
                other = nbr[r]
                del other[m]
                other[root] = other.get(root, 0) + e
                into[r] = into.get(r, 0) + e
            nbr[m] = {}
            into.pop(m, None)
        count -= len(members)
        live[pc[p]] -= 1
        live[pc[root]] -= len(members) - 1
        merged += 1
        largest = max(largest, size)
        heapq.heappush(heap, (ar[root], root))
    for i in range(k):  # resolve to surviving patches (path halving)
        r = i
        while parent[r] != r:
            parent[r] = parent[parent[r]]
            r = parent[r]
        parent[i] = r
    root_of = np.asarray(parent, dtype=np.int64)
    return _Sieved(pcls[root_of][comp], count, merged, largest)


def _quad_area(q: np.ndarray) -> np.ndarray:
    """Shoelace area of (n, 4, 2) quads, relative to their first corner (UTM products lose mm)."""
    r = q - q[:, :1]
    x, y = r[:, :, 0], r[:, :, 1]
    return 0.5 * np.abs(np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1))


def _runs(cells: CellTable, cls: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Whole cells in a row of one swath and one class, joined.

    Returns the run per cell, each run's quad (four corners: for the
    adjacency test) and its polygon with every cell corner along its sides
    (for the union: the zones keep the cells' vertices, so no edge is longer
    than a cell and projecting vertex by vertex stays exact enough).

    A run is consecutive cells (same swath, ``index_in_swath`` + 1) that are
    their whole footprint (unclipped 4-corner cells), share their cut edge
    and go straight; its polygon is the rear corners of the first and the
    front corners of the last cell. The quad's area must equal the cells'
    summed area (1e-7) or the run falls back to its cells. Every later step
    (adjacency, patches, union) works on runs: ~436k cells of the 500 ha
    bench field become far fewer runs, and a run always stays in one patch.
    Other cells (clipped, headland curves, from the store without corners)
    are runs of one with their own polygon.
    """
    n = len(cells)
    polys = cells.polygons_utm
    c = cells.corners_utm
    quad = _quad_area(c)
    parea = shapely.area(polys)
    whole = (
        (shapely.get_type_id(polys) == 3)
        & (shapely.get_num_coordinates(polys) == 5)
        & (np.abs(parea - quad) <= 1e-7 * np.maximum(quad, 1e-12))
    )
    o = np.lexsort((cells.index_in_swath, cells.swath))
    i, j = o[:-1], o[1:]
    d = c[i, 1] - c[i, 0]
    u = d / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)[:, None]

    def off(pt: np.ndarray, base: np.ndarray) -> np.ndarray:
        q = pt - base
        return np.abs(u[:, 0] * q[:, 1] - u[:, 1] * q[:, 0])

    join = (
        (cells.swath[i] == cells.swath[j])
        & (cells.index_in_swath[j] == cells.index_in_swath[i] + 1)
        & (cls[i] == cls[j])
        & whole[i]
        & whole[j]
        & (np.hypot(*(c[i, 1] - c[j, 0]).T) <= _TOUCH_M)
        & (np.hypot(*(c[i, 2] - c[j, 3]).T) <= _TOUCH_M)
        & (off(c[j, 1], c[i, 0]) <= 1e-6)
        & (off(c[j, 2], c[i, 3]) <= 1e-6)
    )
    brk = np.concatenate([[True], ~join])
    rid_sorted = np.cumsum(brk) - 1
    starts = np.flatnonzero(brk)
    ends = np.concatenate([starts[1:], [n]]) - 1
    fi, la = o[starts], o[ends]
    ring = np.stack([c[fi, 0], c[la, 1], c[la, 2], c[fi, 3], c[fi, 0]], axis=1)
    rq = _quad_area(ring[:, :4])
    summed = np.bincount(rid_sorted, weights=parea[o])
    good = (starts != ends) & (np.abs(rq - summed) <= 1e-7 * summed)
    run = np.empty(n, dtype=np.int64)
    run[o] = rid_sorted
    bad_cell = ~good[run]  # runs of one, or runs that failed the area check: their cells
    k = len(starts)
    ids = np.full(n, -1, dtype=np.int64)
    keep_runs = np.flatnonzero(good)
    ids_good = np.full(k, -1, dtype=np.int64)
    ids_good[keep_runs] = np.arange(len(keep_runs))
    ids[~bad_cell] = ids_good[run[~bad_cell]]
    lone = np.flatnonzero(bad_cell)
    ids[lone] = len(keep_runs) + np.arange(len(lone))
    quads = np.concatenate([shapely.polygons(ring[keep_runs]), polys[lone]])
    # the union gets every cell corner along the run's sides, as the cells had them:
    # rear-right of the first, front-right of each, front-left of each backwards,
    # rear-left of the first, closed
    in_run = good[rid_sorted]
    r = rid_sorted[in_run]
    pos = np.arange(n)[in_run] - starts[r]  # place of the cell in its run
    length = (ends - starts + 1)[r]
    cell = o[in_run]
    first = pos == 0
    key = np.concatenate(
        [np.zeros(int(first.sum())), 1 + pos, 1 + length + (length - 1 - pos)]
        + [2 + 2 * length[first], 3 + 2 * length[first]]
    )
    rr = np.concatenate([r[first], r, r, r[first], r[first]])
    xy = np.concatenate(
        [c[cell[first], 0], c[cell, 1], c[cell, 2], c[cell[first], 3], c[cell[first], 0]]
    )
    order = np.lexsort((key, rr))
    sides = shapely.polygons(shapely.linearrings(xy[order], indices=ids_good[rr[order]]))
    return ids, quads, np.concatenate([sides, polys[lone]])


def _dissolve(
    geoms_utm: np.ndarray, cls: np.ndarray, epsg: int, decimals: int
) -> list[tuple[int, Any]]:
    """Union per class in UTM (fast), then to lon/lat and ``snap_valid`` (slivers < 0.1 mm go)."""
    out = []
    for c in np.unique(cls).tolist():
        merged = shapely.union_all(geoms_utm[cls == c])
        wgs = to_wgs84(merged, epsg)
        out.append((int(c), snap_valid(wgs, decimals)))
    return out


def dissolve_zones(
    cells: CellTable,
    n_classes: int = DEFAULT_ZONE_CLASSES,
    max_polygons: int = DEFAULT_MAX_POLYGONS,
    min_patch_m2: float | None = None,
    decimals: int = DEGREE_DECIMALS,
) -> tuple[list[Zone], ZoneSummary]:
    """Rate-class zones of the prescription (see module docstring), highest rate last.

    The sieve counts patches from cell adjacency; if the dissolved geometry
    has more parts than that (cells meeting along < 1 cm), the sieve runs
    again with the cap lowered by the excess, so the cap always holds.
    """
    if len(cells) == 0:
        raise FormatError("prescription has no cells")
    if not 1 <= n_classes <= MAX_ZONE_CLASSES:
        raise FormatError(f"zone classes must be in 1..{MAX_ZONE_CLASSES}, got {n_classes}")
    if max_polygons < n_classes:
        raise FormatError(
            f"max polygons ({max_polygons}) must be at least the zone classes ({n_classes})"
        )
    rate = np.asarray(cells.rate_kg_ha, dtype=float)
    area = np.asarray(cells.area_m2, dtype=float)
    cls0 = _classes(rate, n_classes)
    unit, uquads, ugeoms = _runs(cells, cls0)  # cells joined in runs: all below works on runs
    nu = len(ugeoms)
    ucls0 = np.zeros(nu, dtype=cls0.dtype)
    ucls0[unit] = cls0
    uarea = np.bincount(unit, weights=area, minlength=nu)
    w = area + 1e-12
    class_rate = np.bincount(cls0, weights=w * rate) / np.maximum(
        np.bincount(cls0, weights=w), 1e-300
    )
    a, b = _adjacency(uquads)
    min_patch = 0.0 if min_patch_m2 is None else max(float(min_patch_m2), 0.0)
    n_patches0, _ = _patches(ucls0, a, b)
    target = max_polygons
    while True:
        sv = _sieve(ucls0, class_rate, uarea, a, b, target, min_patch)
        merged = _dissolve(ugeoms, sv.cls, cells.epsg, decimals)
        n_poly = sum(len(polygon_parts(g)) for _, g in merged)
        if n_poly <= max_polygons or sv.n_patches > target or target <= 1:
            break
        target -= n_poly - max_polygons
    cls = sv.cls[unit]
    if n_poly > max_polygons:
        raise FormatError(
            f"the zones need {n_poly} polygons, more than the limit {max_polygons} "
            f"(the field has {sv.n_patches} parts that cannot be merged): use a higher limit"
        )
    # a zone keeps its class's rate (mean of the cells binned into it), so merging
    # changes only the moved cells' rate, never the rate of the cells that stayed
    zone_rate = np.round(class_rate, 2)
    zones = []
    for c, geom in sorted(merged, key=lambda cg: zone_rate[cg[0]]):
        inside = cls == c
        zones.append(
            Zone(
                rate_kg_ha=float(zone_rate[c]),
                polygons=polygon_parts(geom),
                area_m2=float(area[inside].sum()),
                n_cells=int(inside.sum()),
            )
        )
    change = np.abs(zone_rate[cls] - rate)
    moved = cls != cls0
    summary = ZoneSummary(
        n_cells=len(cells),
        n_classes_requested=n_classes,
        n_classes=int(len(np.unique(cls0))),
        n_zones=len(zones),
        n_patches=n_patches0,
        n_polygons=n_poly,
        max_polygons=max_polygons,
        min_patch_m2=min_patch,
        patches_merged=sv.n_merged,
        largest_merged_patch_m2=sv.largest_merged_m2,
        area_reassigned_m2=float(area[moved].sum()),
        max_moved_rate_change_kg_ha=float(change[moved].max(initial=0.0)),
        max_rate_change_kg_ha=float(change.max(initial=0.0)),
        area_weighted_rate_error_kg_ha=float(np.sum(change * area) / max(area.sum(), 1e-12)),
    )
    return zones, summary
