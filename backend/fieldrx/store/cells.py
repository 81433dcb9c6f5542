"""Plan cells in PostGIS: one partition per plan, written by binary COPY, read packed.

``plan_cells`` is partitioned by plan (migration 0002): a plan's cells are COPYed
into a fresh table, its primary key and GiST index are built in bulk and it is
attached. Maintaining the indexes row by row in one shared table was ~20x slower
than the COPY itself. A cell's polygon is stored whole in lon/lat (SRID 4326):
a cell split by a notch or hole is one MultiPolygon (migration 0013_cells).

Reads come back as the one in-memory cell type (:class:`fieldrx.geo.cells.Cells`),
columns fetched packed (``codec.packed_select``) and cut up with numpy.
"""

from __future__ import annotations

import gc
import time
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np
import shapely
from sqlalchemy.orm import Session

from fieldrx.geo.cells import Cells
from fieldrx.geo.crs import lonlat_to_utm_coords, utm_coords_to_lonlat
from fieldrx.store import codec

PLAN_CELLS = codec.CopySpec(
    "plan_cells",
    ("plan_id", "seq", "swath", "index_in_swath", "area_m2", "corners_utm", "geom"),
    ("int4", "int4", "int4", "int4", "float8", "float8[8]", "geometry"),
)
_FIXED = list(zip(PLAN_CELLS.columns[:-1], PLAN_CELLS.types[:-1], strict=True))
_ROW = codec.row_dtype(_FIXED, tail=True)
# a structured dtype always has fields (in order)
_ROW_FIELDS: Mapping[str, Any] = _ROW.fields or {}
EWKB_POLYGON_SRID = 0x20000003  # EWKB type word: Polygon with an SRID
LOAD_CHUNK = 400_000


def driver_connection(session: Session) -> Any:
    """The psycopg connection under the session, inside the session's transaction."""
    return session.connection().connection.driver_connection


def partition_name(plan_id: int) -> str:
    return f"plan_cells_p{int(plan_id)}"


def _one_ring_dtype(k: int) -> np.dtype:
    """A whole plan_cells row whose geometry is a one-ring polygon of k points (EWKB)."""
    return np.dtype(
        [
            *[(name, _ROW_FIELDS[name][0]) for name in _ROW_FIELDS],
            ("bo", "u1"),
            ("gtype", "<u4"),
            ("srid", "<u4"),
            ("nrings", "<u4"),
            ("npts", "<u4"),
            ("xy", "<f8", (k, 2)),
        ]
    )


def _fixed_rows(dtype: np.dtype, plan_id: int, cells: Cells, rows: np.ndarray) -> np.ndarray:
    out = codec.new_rows(dtype, len(rows), len(PLAN_CELLS.columns))
    out["plan_id"] = plan_id
    out["seq"] = cells.seq[rows]
    out["swath"] = cells.swath[rows]
    out["index_in_swath"] = cells.index_in_swath[rows]
    out["area_m2"] = cells.area_m2[rows]
    codec.fill_float8_array(out, cells.corners_utm[rows].reshape(-1, 8), "corners_utm")
    return out


def cell_payload(plan_id: int, cells: Cells) -> Iterator[bytes]:
    """Binary COPY chunks of ``PLAN_CELLS`` (header first, trailer last).

    The EWKB of cells whose polygon is one ring of k points (nearly all) is written by
    numpy straight from the rings, grouped by k: no per-row Python at all. Other cells
    (holes, split cells as MultiPolygons) go through shapely's WKB writer. Rows come
    group by group (the table is keyed by seq; heap order does not matter).
    """
    polys = cells.polygons_utm
    one_ring = (
        (shapely.get_type_id(polys) == 3)
        & (shapely.get_num_interior_rings(polys) == 0)
        & ~shapely.is_empty(polys)
    )
    idx = np.flatnonzero(one_ring)
    rings = shapely.get_exterior_ring(polys[idx])
    npts = shapely.get_num_coordinates(rings)
    ring_off = np.r_[0, np.cumsum(npts)[:-1]].astype(np.int64)
    lonlat = utm_coords_to_lonlat(shapely.get_coordinates(rings), cells.epsg)
    yield codec.HEADER
    for k in np.unique(npts):
        sel = np.flatnonzero(npts == k)
        dt = _one_ring_dtype(int(k))
        for sl in codec.chunks(len(sel)):
            s = sel[sl]
            rows = _fixed_rows(dt, plan_id, cells, idx[s])
            rows["l_tail"] = 17 + 16 * int(k)
            rows["bo"] = 1
            rows["gtype"] = EWKB_POLYGON_SRID
            rows["srid"] = 4326
            rows["nrings"] = 1
            rows["npts"] = k
            rows["xy"] = lonlat[ring_off[s][:, None] + np.arange(int(k))]
            yield rows.tobytes()
    other = np.flatnonzero(~one_ring)
    for sl in codec.chunks(len(other)):
        o = other[sl]
        wgs = shapely.transform(polys[o], lambda c: utm_coords_to_lonlat(c, cells.epsg))
        wkb = shapely.to_wkb(shapely.set_srid(wgs, 4326), include_srid=True)
        rows = _fixed_rows(_ROW, plan_id, cells, o)
        rows["l_tail"] = [len(b) for b in wkb]
        yield codec.interleave(rows, list(wkb))
    yield codec.TRAILER


def check_cells(cells: Cells) -> None:
    """Refuse what the table cannot hold as it is: a polygon that is not a (Multi)Polygon,
    or no UTM zone to convert from. Says which cell."""
    if cells.epsg <= 0:
        raise ValueError("plan cells: no UTM zone (epsg) to store them in lon/lat")
    tid = shapely.get_type_id(cells.polygons_utm)
    bad = np.flatnonzero((tid != 3) & (tid != 6))
    if len(bad):
        i = int(bad[0])
        raise ValueError(
            f"plan cells: cell seq {int(cells.seq[i])} is a "
            f"{cells.polygons_utm[i].geom_type}, not a Polygon or MultiPolygon"
        )


def write_plan_cells(session: Session, plan_id: int, cells: Cells) -> dict[str, float]:
    """Store the cells in the plan's own partition, inside the session's transaction.

    The transaction must have set ``fieldrx.bulk_plan_cells`` when it inserted the plan
    row (migration 0002's trigger then leaves the partition to this function).
    Returns the payload build, COPY and index + attach times (s).
    """
    check_cells(cells)
    t0 = time.perf_counter()
    payload = cell_payload(plan_id, cells)
    build_s = 0.0
    part = partition_name(plan_id)
    conn = driver_connection(session)
    with conn.cursor() as cur:
        cur.execute(
            f"CREATE TABLE {part} (LIKE plan_cells INCLUDING DEFAULTS INCLUDING CONSTRAINTS)"
        )
        with cur.copy(PLAN_CELLS.sql(part)) as cp:
            while True:  # streamed: only one 100k-row chunk in memory at a time
                tb = time.perf_counter()
                chunk = next(payload, None)
                build_s += time.perf_counter() - tb
                if chunk is None:
                    break
                cp.write(chunk)
        t2 = time.perf_counter()
        t1 = t0 + build_s
        cur.execute("SET LOCAL maintenance_work_mem = '256MB'")
        cur.execute(f"ALTER TABLE {part} ADD CONSTRAINT {part}_pkey PRIMARY KEY (plan_id, seq)")
        cur.execute(f"CREATE INDEX {part}_geom_idx ON {part} USING gist (geom)")
        cur.execute(
            f"ALTER TABLE {part} ADD CONSTRAINT {part}_one_plan CHECK (plan_id = {int(plan_id)})"
        )
        # the shape check is each partition's own, not the parent's (migration 0017: under
        # Citus a partition lacking the parent shard's suffixed CHECK is refused)
        cur.execute(
            f"ALTER TABLE {part} ADD CONSTRAINT {part}_geom_polygonal"
            " CHECK (GeometryType(geom) IN ('POLYGON', 'MULTIPOLYGON'))"
        )
        cur.execute(
            f"ALTER TABLE plan_cells ATTACH PARTITION {part} FOR VALUES IN ({int(plan_id)})"
        )
        cur.execute("RESET maintenance_work_mem")
    t3 = time.perf_counter()
    return {"payload_s": t1 - t0, "copy_s": t2 - t1, "index_attach_s": t3 - t2}


_CELL_COLUMNS = [
    ("seq", "int4"),
    ("swath", "int4"),
    ("index_in_swath", "int4"),
    ("area_m2", "float8"),
    ("corners_utm", "float8[8]"),
    ("length(w)", "int4"),
    ("w", "bytea"),
]
_LOAD_SQL = codec.packed_select(
    _CELL_COLUMNS,
    "SELECT seq, swath, index_in_swath, area_m2, corners_utm, ST_AsBinary(geom, 'NDR') AS w"
    " FROM plan_cells WHERE plan_id = %s AND seq >= %s AND seq < %s ORDER BY seq",
)


def _gather(arr: np.ndarray, offs: np.ndarray, width: int, dtype: str) -> np.ndarray:
    """Fixed-width values at byte offsets of a uint8 buffer."""
    return arr[offs[:, None] + np.arange(width)].view(dtype).ravel()


def load_cells(
    session: Session, plan_id: int, epsg: int, lo: int = 0, hi: int | None = None
) -> Cells:
    """The plan's cells with lo <= seq < hi (default all) as ``Cells`` in path order,
    polygons in UTM (and their lon/lat form kept as the WGS84 view).

    The cyclic GC is paused while ~2 million geometry objects are created (each
    gen-2 pass would walk them all again).
    """
    was = gc.isenabled()
    gc.disable()
    try:
        return _load_cells(session, plan_id, epsg, lo, hi)
    finally:
        if was:
            gc.enable()


def _load_cells(session: Session, plan_id: int, epsg: int, lo: int, hi: int | None) -> Cells:
    conn = driver_connection(session)
    if hi is None:
        with conn.cursor() as cur:
            cur.execute("SELECT coalesce(max(seq) + 1, 0) FROM plan_cells WHERE plan_id = %s",
                        (plan_id,))  # fmt: skip
            row = cur.fetchone()
            hi = int(row[0]) if row else 0
    parts: list[tuple[bytes, ...]] = []
    with conn.cursor(binary=True) as cur:
        for a in range(lo, hi, LOAD_CHUNK):
            cur.execute(_LOAD_SQL, (plan_id, a, min(hi, a + LOAD_CHUNK)))
            row = cur.fetchone()
            if row is not None and row[-1]:
                parts.append(tuple(bytes(x) for x in row[:-1]))
    if not parts:
        return Cells.empty(epsg)
    cols = [
        np.concatenate([codec.unpack(p[j], typ) for p in parts])
        for j, (_, typ) in enumerate(_CELL_COLUMNS)
    ]
    seq, swath, idx, area, cutm, lens, wkb = cols
    n = len(seq)
    lens = lens.astype(np.int64)
    g = np.r_[0, np.cumsum(lens)[:-1]]  # WKB starts (little-endian)
    gtype = _gather(wkb, g + 1, 4, "<u4")
    nrings = _gather(wkb, g + 5, 4, "<u4")
    npts = _gather(wkb, g + 9, 4, "<u4")
    simple = (gtype == 3) & (nrings == 1) & (lens == 13 + 16 * npts.astype(np.int64))
    polys = np.empty(n, dtype=object)
    polys_wgs = np.empty(n, dtype=object)
    for k in np.unique(npts[simple]):
        rows = np.flatnonzero(simple & (npts == k))
        kk, m = int(k), len(rows)
        ll = wkb[(g[rows] + 13)[:, None] + np.arange(16 * kk)].view("<f8").reshape(-1, 2)
        xy = lonlat_to_utm_coords(ll, epsg)
        offs = (np.arange(m * kk + 1, step=kk), np.arange(m + 1))
        polys[rows] = shapely.from_ragged_array(shapely.GeometryType.POLYGON, xy, offs)
        polys_wgs[rows] = shapely.from_ragged_array(shapely.GeometryType.POLYGON, ll, offs)
    other = np.flatnonzero(~simple)
    if len(other):
        w = shapely.from_wkb([wkb[a : a + m].tobytes() for a, m in zip(g[other], lens[other],
                                                                       strict=True)])  # fmt: skip
        polys_wgs[other] = w
        polys[other] = shapely.transform(w, lambda c: lonlat_to_utm_coords(c, epsg))
    order = np.argsort(seq, kind="stable")
    if not np.array_equal(order, np.arange(n)):  # aggregate order is not guaranteed
        seq, swath, idx, area, cutm = seq[order], swath[order], idx[order], area[order], cutm[order]
        polys, polys_wgs = polys[order], polys_wgs[order]
    cells = Cells(
        epsg=epsg,
        seq=seq,
        swath=swath,
        index_in_swath=idx,
        corners_utm=cutm.reshape(n, 4, 2),
        area_m2=area,
        polygons_utm=polys,
    )
    cells.adopt_views(polygons_wgs84=polys_wgs)
    return cells


def load_seq_area(session: Session, plan_id: int) -> tuple[np.ndarray, np.ndarray]:
    """(seq, area_m2) of every cell in path order: all a uniform prescription needs."""
    conn = driver_connection(session)
    with conn.cursor(binary=True) as cur:
        cur.execute(
            codec.packed_select(
                [("seq", "int4"), ("area_m2", "float8")],
                "SELECT seq, area_m2 FROM plan_cells WHERE plan_id = %s ORDER BY seq",
            ),
            (plan_id,),
        )
        row = cur.fetchone()
    if row is None or not row[-1]:
        return np.zeros(0, np.int64), np.zeros(0)
    seq = codec.unpack(bytes(row[0]), "int4").astype(np.int64)
    area = codec.unpack(bytes(row[1]), "float8")
    order = np.argsort(seq, kind="stable")
    return seq[order], area[order]


__all__ = [
    "PLAN_CELLS",
    "cell_payload",
    "driver_connection",
    "load_cells",
    "load_seq_area",
    "partition_name",
    "write_plan_cells",
]
