"""Plan storage: plan + grid a ~1,000 ha field and store its ~870k cells in PostGIS.

Prints the planner / grid / store times and the store rate (cells/s) of
FieldRx's path (EWKB built by numpy, binary COPY into the plan's own partition
of plan_cells, bulk build of its PK + GiST indexes, ATTACH), compared in the
same run with (a) the same payload COPYed into an index-free copy of the table
(raw COPY baseline: what the server alone costs) and (b) psycopg's per-row
``copy.write_row`` on a 100k-cell subset. Ends with one JSON line.

Run: .venv/bin/python bench/plan_store.py   (needs PostgreSQL on 127.0.0.1:5432)
"""

from __future__ import annotations

import gzip
import json
import math
import os
import time
import uuid


def main() -> None:
    from alembic import command
    from fieldrx.db.bootstrap import alembic_config, drop_database, ensure_database

    pg = os.environ.get("FIELDRX_TEST_PG", "postgresql://postgres@127.0.0.1:5432")
    url = (
        pg.replace("postgresql://", "postgresql+psycopg://", 1)
        + f"/fieldrx_bench_{uuid.uuid4().hex[:8]}"
    )
    ensure_database(url)
    os.environ["DATABASE_URL"] = url
    try:
        command.upgrade(alembic_config(url), "head")
        run(url)
    finally:
        from fieldrx.db.session import get_engine

        get_engine().dispose()
        drop_database(url)


def tiles_and_rx(s, plan, fld, org_id) -> dict:
    """Tile sizes / times over the field centre at several zooms, and a prescription."""
    from fieldrx.services import tiles
    from fieldrx.services.prescriptions.create import NewPrescription, create_prescription
    from fieldrx.services.prescriptions.meter import MeterSpec
    from fieldrx_edge.metering import SEED001_CALIBRATION
    from geoalchemy2.shape import to_shape

    c = to_shape(fld.boundary).centroid
    out: dict = {}
    t = time.perf_counter()
    spec = NewPrescription(
        name="bench",
        product="",
        model="uniform",
        params={"rate_kg_ha": 700},
        interpolation="cell_mean",
        interpolation_params={},
        fallback_rate_kg_ha=None,
        meter=MeterSpec(SEED001_CALIBRATION.to_dict(), 2.3, 0.8, 2.5),
        machine_id=None,
    )
    rx = create_prescription(s, plan, fld, spec, user_id=None, organisation_id=org_id)
    s.commit()
    out["rx_create_s"] = round(time.perf_counter() - t, 3)
    print(
        f"uniform prescription on {plan.n_cells} cells (load, rate, clamp, COPY rates): "
        f"{out['rx_create_s']:.2f} s"
    )
    from fieldrx.services.prescriptions.versions import get_version

    vid = get_version(s, rx, 1).id
    for z in (12, 14, 15, 16, 17, 18):
        n = 1 << z
        x = int((c.x + 180.0) / 360.0 * n)
        y = int((1.0 - math.asinh(math.tan(math.radians(c.y))) / math.pi) / 2.0 * n)
        ov = tiles.use_overview(z, 2.3, c.y)
        st = tiles.strides(z, 2.3, 5.0, c.y) if ov else (1, 1)
        t = time.perf_counter()
        data = tiles.plan_tile(s, plan.id, z, x, y, ov, st)
        dt = time.perf_counter() - t
        t = time.perf_counter()
        rdata = tiles.prescription_tile(s, plan.id, vid, z, x, y, ov, st)
        rdt = time.perf_counter() - t
        mode = "overview" if ov else "detail"
        gz = len(gzip.compress(data, compresslevel=5))
        rgz = len(gzip.compress(rdata, compresslevel=5))
        print(
            f"tile z{z} ({mode}): plan {len(data) / 1024:.1f} KiB ({gz / 1024:.1f} gzipped) "
            f"in {dt * 1000:.0f} ms, prescription {len(rdata) / 1024:.1f} KiB "
            f"({rgz / 1024:.1f} gzipped) in {rdt * 1000:.0f} ms"
        )
        out[f"tile_z{z}_gz_kib"] = round(gz / 1024, 1)
        out[f"rx_tile_z{z}_gz_kib"] = round(rgz / 1024, 1)
        out[f"tile_z{z}_kib"] = round(len(data) / 1024, 1)
        out[f"tile_z{z}_ms"] = round(dt * 1000)
        out[f"rx_tile_z{z}_kib"] = round(len(rdata) / 1024, 1)
        out[f"rx_tile_z{z}_ms"] = round(rdt * 1000)
    return out


def run(url: str) -> None:
    import psycopg
    import shapely
    from fieldrx.auth.service import create_organisation
    from fieldrx.db.geometry import shape_to_db
    from fieldrx.db.models import Field
    from fieldrx.db.session import get_sessionmaker
    from fieldrx.geo.crs import to_wgs84
    from fieldrx.services.plans import PlanParams, create_plan
    from fieldrx.store import load_cells
    from fieldrx.store.cells import PLAN_CELLS, cell_payload
    from shapely.geometry import Polygon

    # 1,000 ha: 4 km x 2.5 km rectangle, slightly rotated, near the demo farm (UTM 49N)
    epsg = 32649
    cx, cy = 600_000.0, 3_555_000.0
    a = math.radians(7.0)
    pts = [(-2000, -1250), (2000, -1250), (2000, 1250), (-2000, 1250)]
    utm = Polygon(
        [
            (cx + x * math.cos(a) - y * math.sin(a), cy + x * math.sin(a) + y * math.cos(a))
            for x, y in pts
        ]
    )
    wgs = to_wgs84(utm, epsg)
    sm = get_sessionmaker()
    with sm() as s:
        org = create_organisation(s, f"bench-{uuid.uuid4().hex[:6]}")
        fld = Field(
            organisation_id=org.id,
            name="1000 ha",
            boundary=shape_to_db(shapely.MultiPolygon([wgs])),
            utm_epsg=epsg,
            area_m2=utm.area,
        )
        s.add(fld)
        s.commit()
        t0 = time.perf_counter()
        plan = create_plan(s, fld, PlanParams(swath_width_m=2.3, cell_length_m=5.0), org.id)
        s.commit()
        total = time.perf_counter() - t0
        tm = plan.metrics["timings_s"]
        n = plan.n_cells
        print(f"field {utm.area / 1e4:.0f} ha, {n} cells")
        print(
            f"plan {tm['plan']:.2f} s, grid {tm['grid']:.2f} s, store {tm['store']:.2f} s "
            f"(COPY {tm['store_copy']:.2f} s, index build + attach {tm['store_index']:.2f} s), "
            f"total {total:.2f} s"
        )
        store_rate = n / tm["store"]
        copy_rate = n / tm["store_copy"]
        print(
            f"store (transform + build + COPY + index): {store_rate:,.0f} cells/s; "
            f"COPY alone {copy_rate:,.0f}"
        )

        # baselines on the same rows: rebuild the grid (pure) and its payload
        from fieldrx.geo.coverage import plan_coverage
        from fieldrx.geo.grid import build_grid

        grid = build_grid(plan_coverage(utm, 2.3), utm, 5.0, epsg=epsg)
        polys = grid.polygons_utm
        t = time.perf_counter()
        payload = list(cell_payload(plan.id, grid))
        build_s = time.perf_counter() - t
        print(f"payload build (EWKB by numpy): {build_s:.2f} s")
        wgs_polys = to_wgs84(polys, epsg)
        t = time.perf_counter()
        back = load_cells(s, plan.id, epsg)
        cols_s = time.perf_counter() - t
        _ = (back.centroids_utm, back.corners_wgs84)  # what the old loader computed eagerly
        load_s = time.perf_counter() - t
        print(
            f"load back as Cells (+ centres and lon/lat corners): {load_s:.2f} s "
            f"({n / load_s:,.0f} cells/s; columns and polygons alone {cols_s:.2f} s)"
        )
        extra = tiles_and_rx(s, plan, fld, org.id)
    dsn = url.replace("postgresql+psycopg://", "postgresql://", 1)
    with psycopg.connect(dsn, options="-c jit=off") as conn:
        conn.execute("CREATE UNLOGGED TABLE bench_cells (LIKE plan_cells)")
        t = time.perf_counter()
        with conn.cursor() as cur:
            PLAN_CELLS.write_payload(cur, payload, "bench_cells")
        raw_s = time.perf_counter() - t
        conn.execute("TRUNCATE bench_cells")
        m = min(n, 100_000)
        wkb = shapely.to_wkb(shapely.set_srid(wgs_polys[:m], 4326), include_srid=True, hex=True)
        corners = grid.corners_utm.reshape(-1, 8)[:m].tolist()
        t = time.perf_counter()
        with (
            conn.cursor() as cur,
            cur.copy(
                "COPY bench_cells "
                "(plan_id, seq, swath, index_in_swath, area_m2, corners_utm, geom) "
                "FROM STDIN"
            ) as cp,
        ):
            for i in range(m):
                cp.write_row(
                    (
                        1,
                        int(grid.seq[i]),
                        int(grid.swath[i]),
                        0,
                        float(grid.area_m2[i]),
                        corners[i],
                        wkb[i],
                    )
                )
        row_s = time.perf_counter() - t
        conn.execute("DROP TABLE bench_cells")
    raw_rate = n / raw_s
    row_rate = m / row_s
    print(f"baseline raw COPY, same payload, no indexes: {raw_rate:,.0f} cells/s")
    print(f"baseline psycopg write_row (text, {m} cells): {row_rate:,.0f} cells/s")
    print(
        f"ratio store/raw COPY {store_rate / raw_rate:.2f}, "
        f"COPY into partition/raw {copy_rate / raw_rate:.2f}, "
        f"store/write_row {store_rate / row_rate:.2f}"
    )
    print(
        json.dumps(
            {
                "bench": "plan_store",
                "n_cells": n,
                "area_ha": round(utm.area / 1e4, 1),
                "plan_s": tm["plan"],
                "grid_s": tm["grid"],
                "store_s": tm["store"],
                "copy_s": tm["store_copy"],
                "index_attach_s": tm["store_index"],
                "total_s": round(total, 3),
                "store_cells_per_s": round(store_rate),
                "raw_copy_cells_per_s": round(raw_rate),
                "write_row_cells_per_s": round(row_rate),
                "store_vs_raw_copy": round(store_rate / raw_rate, 3),
                "store_vs_write_row": round(store_rate / row_rate, 3),
                "load_s": round(load_s, 3),
                "load_columns_s": round(cols_s, 3),
                **extra,
            }
        )
    )


if __name__ == "__main__":
    main()
