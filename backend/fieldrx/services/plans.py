"""Plans in PostGIS: run the pure planner (fieldrx.geo) and store its grid fast.

The plan row and its ``plan_cells`` rows are written in one transaction; the
cells go through a binary COPY (services.copy) so a 1,000 ha field with about
870k cells stores in seconds. Cells are read back as a ``CellTable`` for the
prescription layer.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
from geoalchemy2.shape import to_shape
from sqlalchemy import text
from sqlalchemy.orm import Session

from fieldrx.agronomy.cells import CellTable
from fieldrx.db.geometry import shape_to_db
from fieldrx.db.models import Field, Plan
from fieldrx.geo import PlanningError
from fieldrx.geo.coverage import plan_coverage
from fieldrx.geo.crs import to_utm, to_wgs84
from fieldrx.geo.grid import MAX_CELLS, MIN_CELL_LENGTH_M, Grid, build_grid, inside_centres
from fieldrx.services import copy as pgcopy

POLYGON = 3


@dataclass
class PlanParams:
    swath_width_m: float = 2.3
    cell_length_m: float = 5.0
    heading: str = "longest_edge"
    angle_deg: float | None = None
    headland_passes: int = 0
    start_corner: str = "sw"
    headland_order: str = "first"
    min_cell_fraction: float = 0.1
    turn_radius_m: float = 6.0
    reverse: bool = False
    pattern: str = "boustrophedon"


def driver_connection(session: Session) -> Any:
    """The psycopg connection under the session, inside the session's transaction."""
    return session.connection().connection.driver_connection


def field_utm(field: Field) -> Any:
    return to_utm(to_shape(field.boundary), field.utm_epsg)


def as_polygons(geoms: np.ndarray) -> tuple[np.ndarray, int]:
    """Clipped cells as single Polygons (the column type).

    A cell cut in two by a notch or hole keeps its largest part; the count of
    such cells is returned so the plan metrics can report it (area_m2 keeps
    the whole clipped area).
    """
    out = np.asarray(geoms, dtype=object).copy()
    bad = np.flatnonzero(shapely.get_type_id(out) != POLYGON)
    for i in bad:
        parts = [
            g for g in shapely.get_parts(shapely.get_parts(out[i])) if g.geom_type == "Polygon"
        ]
        out[i] = max(parts, key=lambda g: g.area) if parts else shapely.Polygon()
    return out, len(bad)


_CELL_DTYPE = np.dtype(
    [
        ("nf", ">i2"),
        ("l_plan", ">i4"),
        ("plan", ">i4"),
        ("l_seq", ">i4"),
        ("seq", ">i4"),
        ("l_swath", ">i4"),
        ("swath", ">i4"),
        ("l_idx", ">i4"),
        ("idx", ">i4"),
        ("l_area", ">i4"),
        ("area", ">f8"),
        *pgcopy.float8_array_fields(8),
        ("l_geom", ">i4"),
    ]
)


def partition_name(plan_id: int) -> str:
    return f"plan_cells_p{int(plan_id)}"


def cell_copy_sql(table: str = "plan_cells") -> str:
    return (
        f"COPY {table} (plan_id, seq, swath, index_in_swath, area_m2, corners_utm, geom) "
        "FROM STDIN (FORMAT BINARY)"
    )


def cell_copy_payloads(
    plan_id: int,
    seq: np.ndarray,
    swath: np.ndarray,
    index_in_swath: np.ndarray,
    area_m2: np.ndarray,
    corners_utm: np.ndarray,
    polygons_wgs84: np.ndarray,
) -> Any:
    """Yield binary COPY chunks for plan_cells (header first, trailer last), EWKB per row
    from shapely (the general path; ``fast_cell_copy_payloads`` is the vectorised one)."""
    n = len(seq)
    yield pgcopy.HEADER
    corners = np.asarray(corners_utm, dtype=float).reshape(n, 8)
    for sl in pgcopy.chunks(n):
        wkb = shapely.to_wkb(shapely.set_srid(polygons_wgs84[sl], 4326), include_srid=True)
        rows = _fixed_rows(
            _CELL_DTYPE, plan_id, seq[sl], swath[sl], index_in_swath[sl], area_m2[sl], corners[sl]
        )
        rows["l_geom"] = [len(b) for b in wkb]
        yield pgcopy.interleave(rows, list(wkb))
    yield pgcopy.TRAILER


def _fixed_rows(
    dtype: np.dtype,
    plan_id: int,
    seq: np.ndarray,
    swath: np.ndarray,
    idx: np.ndarray,
    area: np.ndarray,
    corners8: np.ndarray,
) -> np.ndarray:
    rows = np.zeros(len(seq), dtype=dtype)
    rows["nf"] = 7
    rows["l_plan"] = rows["l_seq"] = rows["l_swath"] = rows["l_idx"] = 4
    rows["plan"] = plan_id
    rows["seq"] = seq
    rows["swath"] = swath
    rows["idx"] = idx
    rows["l_area"] = 8
    rows["area"] = area
    pgcopy.fill_float8_array(rows, corners8)
    return rows


EWKB_POLYGON_SRID = 0x20000003  # EWKB type word: Polygon with an SRID


def _simple_dtype(k: int) -> np.dtype:
    """A whole plan_cells row whose geometry is a one-ring polygon of k points (EWKB)."""
    return np.dtype(
        [
            *[(name, _CELL_DTYPE.fields[name][0]) for name in _CELL_DTYPE.names],
            ("bo", "u1"),
            ("gtype", "<u4"),
            ("srid", "<u4"),
            ("nrings", "<u4"),
            ("npts", "<u4"),
            ("xy", "<f8", (k, 2)),
        ]
    )


def _to_lonlat(xy: np.ndarray, epsg: int) -> np.ndarray:
    """UTM -> lon/lat for millions of points, split over two threads (pyproj frees the GIL)."""
    from concurrent.futures import ThreadPoolExecutor

    from pyproj import Transformer

    n = len(xy)
    out = np.empty_like(xy)

    def work(sl: slice) -> None:
        tr = Transformer.from_crs(epsg, 4326, always_xy=True)  # one per thread
        lon, lat = tr.transform(xy[sl, 0], xy[sl, 1])
        out[sl, 0], out[sl, 1] = lon, lat

    if n < 200_000:
        work(slice(0, n))
    else:
        with ThreadPoolExecutor(2) as ex:
            list(ex.map(work, [slice(0, n // 2), slice(n // 2, n)]))
    return out


def fast_cell_copy_payloads(
    plan_id: int,
    seq: np.ndarray,
    swath: np.ndarray,
    index_in_swath: np.ndarray,
    area_m2: np.ndarray,
    corners_utm: np.ndarray,
    polygons_utm: np.ndarray,
    epsg: int,
) -> Any:
    """Binary COPY chunks with the EWKB written by numpy straight from the UTM rings.

    Cells whose polygon is one ring of k points (nearly all) are grouped by k and
    each group is one structured array: no per-row Python at all. Cells with
    holes go through shapely's WKB writer. Rows are emitted group by group
    (the table is keyed by seq; heap order does not matter).
    """
    n = len(seq)
    polys = np.asarray(polygons_utm, dtype=object)
    rings, ring_poly = shapely.get_rings(polys, return_index=True)
    n_rings = np.bincount(ring_poly, minlength=n)
    npts = shapely.get_num_coordinates(rings)
    ring_off = np.r_[0, np.cumsum(npts)[:-1]]
    lonlat = _to_lonlat(shapely.get_coordinates(rings), epsg)
    first_ring = np.r_[0, np.cumsum(n_rings)[:-1]]
    corners = np.asarray(corners_utm, dtype=float).reshape(n, 8)
    simple = n_rings == 1
    k_of = np.zeros(n, np.int64)
    k_of[simple] = npts[first_ring[simple]]
    yield pgcopy.HEADER
    for k in np.unique(k_of[simple]):
        rows_k = np.flatnonzero(simple & (k_of == k))
        dt = _simple_dtype(int(k))
        for sl in pgcopy.chunks(len(rows_k)):
            r = rows_k[sl]
            rows = _fixed_rows(
                dt, plan_id, seq[r], swath[r], index_in_swath[r], area_m2[r], corners[r]
            )
            rows["l_geom"] = 17 + 16 * int(k)
            rows["bo"] = 1
            rows["gtype"] = EWKB_POLYGON_SRID
            rows["srid"] = 4326
            rows["nrings"] = 1
            rows["npts"] = k
            start = ring_off[first_ring[r]]
            rows["xy"] = lonlat[start[:, None] + np.arange(int(k))]
            yield rows.tobytes()
    other = np.flatnonzero(~simple)
    if len(other):
        wgs = shapely.transform(polys[other], lambda c: _to_lonlat(c, epsg))
        wkb = shapely.to_wkb(shapely.set_srid(wgs, 4326), include_srid=True)
        rows = _fixed_rows(
            _CELL_DTYPE,
            plan_id,
            seq[other],
            swath[other],
            index_in_swath[other],
            area_m2[other],
            corners[other],
        )
        rows["l_geom"] = [len(b) for b in wkb]
        yield pgcopy.interleave(rows, list(wkb))
    yield pgcopy.TRAILER


def copy_cells(session: Session, plan_id: int, grid: Grid, epsg: int) -> dict[str, float]:
    """Store the grid's cells in the plan's own partition, inside the session's transaction.

    plan_cells is partitioned by plan (migration 0002): COPY into a fresh table,
    build its primary key and GiST index in bulk, attach it. Maintaining the
    indexes row by row in one shared table was ~20x slower than the COPY itself.
    """
    t0 = time.perf_counter()
    polys, n_multi = as_polygons(grid.polygons)
    payload = fast_cell_copy_payloads(
        plan_id,
        grid.seq,
        grid.swath,
        grid.index_in_swath,
        grid.area_m2,
        grid.corners_utm,
        polys,
        epsg,
    )
    build_s = 0.0
    part = partition_name(plan_id)
    conn = driver_connection(session)
    with conn.cursor() as cur:
        cur.execute(f"CREATE TABLE {part} (LIKE plan_cells INCLUDING DEFAULTS)")
        with cur.copy(cell_copy_sql(part)) as cp:
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
            f"ALTER TABLE {part} ADD CONSTRAINT {part}_one_plan CHECK (plan_id = {plan_id})"
        )
        cur.execute(f"ALTER TABLE plan_cells ATTACH PARTITION {part} FOR VALUES IN ({plan_id})")
        cur.execute("RESET maintenance_work_mem")
    t3 = time.perf_counter()
    return {
        "payload_s": t1 - t0,
        "copy_s": t2 - t1,
        "index_attach_s": t3 - t2,
        "multipart_cells": n_multi,
    }


def delete_plan(session: Session, plan: Plan) -> None:
    """Delete the plan; a trigger (migration 0002) drops its partition, no row-by-row delete.

    Dropping a partition needs a short exclusive lock on plan_cells; the lock wait is
    bounded so a busy table makes this fail (sqlalchemy OperationalError) instead of
    queueing every tile request behind it.
    """
    session.execute(text("SET LOCAL lock_timeout = '5s'"))
    session.delete(plan)
    session.flush()


def check_plan_cost(area_m2: float, params: PlanParams) -> None:
    """Refuse, before any planning, a plan whose grid would exceed ``MAX_CELLS``.

    Every cell is at most one swath wide and one cell long, so a field of area A
    needs about A / (w L) cells; a 0.05 m swath on 500 ha would be ~20 million
    cells and minutes of CPU before ``build_grid``'s own (exact) count could refuse
    it. Non-finite or non-positive values are left to the planner's own messages.
    """
    w, length = float(params.swath_width_m), float(params.cell_length_m)
    if not (np.isfinite(w) and np.isfinite(length) and w > 0 and length >= MIN_CELL_LENGTH_M):
        return
    n_est = float(area_m2) / (w * length)
    if n_est > MAX_CELLS:
        raise PlanningError(
            f"swath width {w:g} m and cell length {length:g} m give about {n_est:,.0f} cells on "
            f"this {area_m2 / 10_000:,.1f} ha field, more than {MAX_CELLS} (the limit): "
            "use a wider swath or longer cells"
        )


def plan_in_worker(
    database_url: str, field_id: int, params: PlanParams, organisation_id: int, time_limit_s: float
) -> int:
    """``create_plan`` and commit on a connection of its own (run by ``services.bounded``
    in a child process); returns the new plan's id."""
    from sqlalchemy.orm import Session as OrmSession

    from fieldrx.db.session import make_engine

    engine = make_engine(database_url)
    try:
        with OrmSession(engine) as session:
            ms = max(1000, int(time_limit_s * 1000))
            session.execute(text(f"SET statement_timeout = {ms}"))
            field = session.get(Field, field_id)
            if field is None:
                raise PlanningError(f"field {field_id} was deleted while planning")
            plan = create_plan(session, field, params, organisation_id)
            session.commit()
            return int(plan.id)
    finally:
        engine.dispose()


def create_plan_bounded(
    session: Session, field: Field, params: PlanParams, organisation_id: int
) -> Plan:
    """``create_plan`` with its cost checked first and run off the server process with the
    ``FIELDRX_PLAN_TIME_LIMIT_S`` limit (services.bounded); commits in the worker.

    The session's transaction is ended first: no transaction of the server stays open
    while the worker plans."""
    field_id, area_m2 = field.id, field.area_m2
    session.rollback()
    from fieldrx.services.bounded import run_bounded
    from fieldrx.settings import get_settings

    check_plan_cost(area_m2, params)
    limit = get_settings().plan_time_limit_s
    url = session.get_bind().url.render_as_string(hide_password=False)
    plan_id = run_bounded(
        plan_in_worker,
        url,
        field_id,
        params,
        organisation_id,
        limit,
        time_limit_s=limit,
        what="planning",
    )
    plan = session.get(Plan, plan_id)
    assert plan is not None
    return plan


def create_plan(session: Session, field: Field, params: PlanParams, organisation_id: int) -> Plan:
    """Plan + grid + store (flushes, does not commit). Raises ``PlanningError``."""
    t0 = time.perf_counter()
    check_plan_cost(field.area_m2, params)
    boundary = field_utm(field)
    cov = plan_coverage(
        boundary,
        swath_width_m=params.swath_width_m,
        heading=params.heading,  # type: ignore[arg-type]
        angle_deg=params.angle_deg,
        headland_passes=params.headland_passes,
        start_corner=params.start_corner,  # type: ignore[arg-type]
        headland_order=params.headland_order,  # type: ignore[arg-type]
        turn_radius_m=params.turn_radius_m,
        reverse=params.reverse,
        pattern=params.pattern,
    )
    t_plan = time.perf_counter()
    grid = build_grid(
        cov,
        boundary,
        cell_length_m=params.cell_length_m,
        min_cell_fraction=params.min_cell_fraction,
    )
    t_grid = time.perf_counter()
    metrics: dict[str, Any] = dict(cov.metrics())
    metrics["n_cells"] = len(grid)
    metrics["cells_uncovered_m2"] = round(grid.uncovered_m2, 3)
    metrics["epsg"] = field.utm_epsg
    route = to_wgs84(cov.route(), field.utm_epsg)
    plan = Plan(
        organisation_id=organisation_id,
        field_id=field.id,
        params={k: v for k, v in params.__dict__.items()},
        metrics=metrics,
        heading_deg=float(cov.heading_deg),
        n_cells=len(grid),
        route=shape_to_db(route),
    )
    # this transaction attaches a bulk-built partition itself (migration 0002 trigger)
    session.execute(text("SELECT set_config('fieldrx.bulk_plan_cells', 'on', true)"))
    session.add(plan)
    session.flush()
    session.execute(text("SELECT set_config('fieldrx.bulk_plan_cells', 'off', true)"))
    store = copy_cells(session, plan.id, grid, field.utm_epsg)
    t_store = time.perf_counter()
    metrics["multipart_cells"] = store.pop("multipart_cells")
    metrics["timings_s"] = {
        "plan": round(t_plan - t0, 4),
        "grid": round(t_grid - t_plan, 4),
        "store": round(t_store - t_grid, 4),
        "store_copy": round(store["copy_s"], 4),
        "store_index": round(store["index_attach_s"], 4),
        "total": round(t_store - t0, 4),
    }
    plan.metrics = metrics
    session.flush()
    return plan


def plan_summary(plan: Plan) -> dict[str, Any]:
    p = plan.params or {}
    return {
        "id": plan.id,
        "field_id": plan.field_id,
        "params": p,
        "heading_deg": plan.heading_deg,
        "n_cells": plan.n_cells,
        "metrics": plan.metrics,
        "created_at": plan.created_at.isoformat() if plan.created_at else None,
    }


def cells_page(session: Session, plan_id: int, limit: int, offset: int) -> list[dict[str, Any]]:
    """GeoJSON features of cells offset .. offset+limit-1 in path order (seq is 0..n-1)."""
    rows = session.execute(
        text(
            "SELECT seq, swath, index_in_swath, area_m2, ST_AsGeoJSON(geom, 9) "
            "FROM plan_cells WHERE plan_id = :p AND seq >= :a AND seq < :b ORDER BY seq"
        ),
        {"p": plan_id, "a": offset, "b": offset + limit},
    )
    return [
        {
            "type": "Feature",
            "id": seq,
            "geometry": json.loads(gj),
            "properties": {
                "seq": seq,
                "swath": swath,
                "index_in_swath": idx,
                "area_m2": round(area, 3),
            },
        }
        for seq, swath, idx, area, gj in rows
    ]


def _to_utm(lonlat: np.ndarray, epsg: int) -> np.ndarray:
    """lon/lat -> UTM for millions of points on two threads (pyproj frees the GIL)."""
    from concurrent.futures import ThreadPoolExecutor

    from pyproj import Transformer

    n = len(lonlat)
    out = np.empty_like(lonlat)

    def work(sl: slice) -> None:
        tr = Transformer.from_crs(4326, epsg, always_xy=True)
        x, y = tr.transform(lonlat[sl, 0], lonlat[sl, 1])
        out[sl, 0], out[sl, 1] = x, y

    if n < 200_000:
        work(slice(0, n))
    else:
        with ThreadPoolExecutor(2) as ex:
            list(ex.map(work, [slice(0, n // 2), slice(n // 2, n)]))
    return out


_EMPTY_TABLE_ARRAYS = {
    "seq": np.zeros(0, np.int64),
    "swath": np.zeros(0, np.int64),
    "polygons_utm": np.zeros(0, dtype=object),
    "centroids_utm": np.zeros((0, 2)),
    "corners_utm": np.zeros((0, 4, 2)),
    "corners_wgs84": np.zeros((0, 4, 2)),
    "area_m2": np.zeros(0),
}
LOAD_CHUNK = 400_000

# One row per chunk: every column packed into one bytea in seq order (int4send /
# float8send / array_send are the binary wire forms), so 870k cells cross the
# wire as a handful of values instead of 870k rows.
_LOAD_SQL = """
SELECT string_agg(int4send(seq), ''::bytea), string_agg(int4send(swath), ''::bytea),
       string_agg(float8send(area_m2), ''::bytea), string_agg(array_send(corners_utm), ''::bytea),
       string_agg(int4send(length(w)), ''::bytea), string_agg(w, ''::bytea), count(*)
FROM (SELECT seq, swath, area_m2, corners_utm, ST_AsBinary(geom, 'NDR') AS w
      FROM plan_cells WHERE plan_id = %s AND seq >= %s AND seq < %s ORDER BY seq) s
"""


def _gather(arr: np.ndarray, offs: np.ndarray, width: int, dtype: str) -> np.ndarray:
    """Fixed-width values at byte offsets of a uint8 buffer."""
    return arr[offs[:, None] + np.arange(width)].view(dtype).ravel()


def _ring_centroids(xy: np.ndarray) -> np.ndarray:
    """Area centroids of closed rings (m, k, 2) by the shoelace formula (vectorised)."""
    o = xy[:, :1, :]
    r = xy - o
    x0, y0 = r[:, :-1, 0], r[:, :-1, 1]
    x1, y1 = r[:, 1:, 0], r[:, 1:, 1]
    cr = x0 * y1 - x1 * y0
    a = cr.sum(axis=1) / 2.0
    safe = np.where(np.abs(a) > 1e-12, a, 1.0)
    cx = ((x0 + x1) * cr).sum(axis=1) / (6.0 * safe)
    cy = ((y0 + y1) * cr).sum(axis=1) / (6.0 * safe)
    c = np.stack([cx, cy], axis=1) + o[:, 0, :]
    flat = np.abs(a) <= 1e-12
    if flat.any():
        c[flat] = xy[flat, :-1].mean(axis=1)
    return c


def load_cell_table(session: Session, plan: Plan, epsg: int) -> CellTable:
    """See ``_load_cell_table``; the cyclic GC is paused while ~2 million geometry objects
    are created (each gen-2 pass would walk them all again)."""
    import gc

    was = gc.isenabled()
    gc.disable()
    try:
        return _load_cell_table(session, plan, epsg)
    finally:
        if was:
            gc.enable()


def _load_cell_table(session: Session, plan: Plan, epsg: int) -> CellTable:
    """All cells of a plan as a CellTable (path order), polygons back in UTM.

    Columns arrive packed (see _LOAD_SQL) and are cut up with numpy; one-ring
    polygons (nearly all) are rebuilt from their coordinates grouped by vertex
    count with ``shapely.from_ragged_array``. ~15 s -> a few s for 870k cells.
    """
    conn = driver_connection(session)
    parts: list[tuple[bytes, ...]] = []
    total = max(int(plan.n_cells), 0)
    with conn.cursor(binary=True) as cur:
        a = 0
        while True:
            cur.execute(_LOAD_SQL, (plan.id, a, a + LOAD_CHUNK))
            row = cur.fetchone()
            if row is not None and row[6]:
                parts.append(tuple(bytes(x) for x in row[:6]))
            a += LOAD_CHUNK
            if a >= total:
                break
    if not parts:
        return CellTable(epsg=epsg, **_EMPTY_TABLE_ARRAYS)  # type: ignore[arg-type]
    seq = np.concatenate([np.frombuffer(p[0], ">i4") for p in parts]).astype(np.int64)
    n = len(seq)
    swath = np.concatenate([np.frombuffer(p[1], ">i4") for p in parts]).astype(np.int64)
    area = np.concatenate([np.frombuffer(p[2], ">f8") for p in parts]).astype(float)
    arr_dt = np.dtype([("hdr", "V20"), ("v", [("l", ">i4"), ("x", ">f8")], (8,))])
    cutm = np.concatenate([np.frombuffer(p[3], arr_dt)["v"]["x"] for p in parts]).astype(float)
    cutm = cutm.reshape(n, 4, 2)
    lens = np.concatenate([np.frombuffer(p[4], ">i4") for p in parts]).astype(np.int64)
    wkb = np.frombuffer(b"".join(p[5] for p in parts), np.uint8)
    g = np.r_[0, np.cumsum(lens)[:-1]]  # WKB starts (little-endian polygons)
    nrings = _gather(wkb, g + 5, 4, "<u4")
    npts = _gather(wkb, g + 9, 4, "<u4")
    simple = (nrings == 1) & (lens == 13 + 16 * npts.astype(np.int64))
    polys = np.empty(n, dtype=object)
    polys_wgs = np.empty(n, dtype=object)
    cent = np.full((n, 2), np.nan)
    for k in np.unique(npts[simple]):
        rows = np.flatnonzero(simple & (npts == k))
        kk, m = int(k), len(rows)
        ll = wkb[(g[rows] + 13)[:, None] + np.arange(16 * kk)].view("<f8").reshape(-1, 2)
        xy = _to_utm(ll, epsg)
        offs = (np.arange(m * kk + 1, step=kk), np.arange(m + 1))
        polys[rows] = shapely.from_ragged_array(shapely.GeometryType.POLYGON, xy, offs)
        polys_wgs[rows] = shapely.from_ragged_array(shapely.GeometryType.POLYGON, ll, offs)
        if kk <= 5:  # grid quads are convex: the area centroid lies inside
            cent[rows] = _ring_centroids(xy.reshape(m, kk, 2))
        else:
            cent[rows] = inside_centres(polys[rows])
    other = np.flatnonzero(~simple)
    if len(other):
        chunks = [wkb[a : a + m].tobytes() for a, m in zip(g[other], lens[other], strict=True)]
        w = shapely.from_wkb(chunks)
        polys_wgs[other] = w
        polys[other] = shapely.transform(w, lambda c: _to_utm(c, epsg))
        cent[other] = inside_centres(polys[other])
    order = np.argsort(seq, kind="stable")
    if not np.array_equal(order, np.arange(n)):  # aggregate order is not guaranteed
        seq, swath, area, cutm = seq[order], swath[order], area[order], cutm[order]
        polys, polys_wgs, cent = polys[order], polys_wgs[order], cent[order]
    table = CellTable(
        epsg=epsg,
        seq=seq,
        swath=swath,
        polygons_utm=polys,
        centroids_utm=cent,
        corners_utm=cutm,
        corners_wgs84=_to_lonlat(cutm.reshape(-1, 2), epsg).reshape(n, 4, 2),
        area_m2=area,
    )
    table.set_polygons_wgs84(polys_wgs)
    return table


def load_seq_area(session: Session, plan: Plan) -> tuple[np.ndarray, np.ndarray]:
    """(seq, area_m2) of every cell in path order: all a uniform prescription needs."""
    conn = driver_connection(session)
    with conn.cursor(binary=True) as cur:
        cur.execute(
            "SELECT string_agg(int4send(seq), ''::bytea), string_agg(float8send(area_m2), "
            "''::bytea) FROM (SELECT seq, area_m2 FROM plan_cells WHERE plan_id = %s "
            "ORDER BY seq) c",
            (plan.id,),
        )
        row = cur.fetchone()
    if row is None or row[0] is None:
        return np.zeros(0, np.int64), np.zeros(0)
    seq = np.frombuffer(bytes(row[0]), ">i4").astype(np.int64)
    area = np.frombuffer(bytes(row[1]), ">f8").astype(float)
    order = np.argsort(seq, kind="stable")
    return seq[order], area[order]
