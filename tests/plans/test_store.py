"""The fast COPY writer and the packed reader agree with the plain shapely/PostGIS paths."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon
from sqlalchemy import text

EPSG = 32649
X0, Y0 = 624000.0, 3556000.0


def _cells() -> tuple[np.ndarray, np.ndarray]:
    """UTM cells: rectangles (5 points), a triangle (4), a 7-point cell and one with a hole."""
    polys = [shapely.box(X0 + 2.3 * i, Y0, X0 + 2.3 * (i + 1), Y0 + 5) for i in range(6)]
    polys.append(Polygon([(X0, Y0 + 5), (X0 + 2.3, Y0 + 5), (X0, Y0 + 9)]))
    polys.append(
        Polygon(
            [
                (X0, Y0 + 10),
                (X0 + 2, Y0 + 10),
                (X0 + 2.3, Y0 + 11),
                (X0 + 2.3, Y0 + 15),
                (X0 + 1, Y0 + 15.5),
                (X0, Y0 + 15),
            ]
        )
    )
    outer = shapely.box(X0 + 3, Y0 + 10, X0 + 5.3, Y0 + 15)
    polys.append(outer.difference(shapely.box(X0 + 3.5, Y0 + 11, X0 + 4, Y0 + 12)))
    polys = np.array(polys, dtype=object)
    corners = np.stack(
        [np.asarray(shapely.oriented_envelope(p).exterior.coords)[:4] for p in polys]
    )
    return polys, corners


def _plan(db, org_id: int) -> int:
    from fieldrx.db.models import Field, Plan
    from fieldrx.geo.crs import to_wgs84
    from geoalchemy2.shape import from_shape
    from shapely.geometry import LineString, MultiPolygon

    f = Field(
        organisation_id=org_id,
        name="s",
        utm_epsg=EPSG,
        area_m2=100.0,
        boundary=from_shape(
            MultiPolygon([to_wgs84(shapely.box(X0, Y0, X0 + 20, Y0 + 20), EPSG)]), 4326
        ),
    )
    db.add(f)
    db.flush()
    p = Plan(
        organisation_id=org_id,
        field_id=f.id,
        params={},
        metrics={},
        heading_deg=0.0,
        n_cells=9,
        route=from_shape(LineString([(112.3, 32.1), (112.31, 32.1)]), 4326),
    )
    db.add(p)
    db.flush()
    return p.id


def test_fast_payload_equals_shapely_payload(db, org) -> None:
    from fieldrx.geo.crs import to_wgs84
    from fieldrx.services.plans import (
        cell_copy_payloads,
        cell_copy_sql,
        driver_connection,
        fast_cell_copy_payloads,
    )

    polys, corners = _cells()
    n = len(polys)
    seq, swath, idx = np.arange(n), np.arange(n) // 3, np.arange(n) % 3
    area = shapely.area(polys)
    conn = driver_connection(db)
    with conn.cursor() as cur:
        for name, payload in (
            ("a", cell_copy_payloads(7, seq, swath, idx, area, corners, to_wgs84(polys, EPSG))),
            ("b", fast_cell_copy_payloads(7, seq, swath, idx, area, corners, polys, EPSG)),
        ):
            cur.execute(f"CREATE TEMP TABLE t_{name} (LIKE plan_cells)")
            with cur.copy(cell_copy_sql(f"t_{name}")) as cp:
                for chunk in payload:
                    cp.write(chunk)
    rows = db.execute(
        text(
            "SELECT a.seq, ST_Equals(a.geom, b.geom), ST_HausdorffDistance(a.geom, b.geom), "
            "ST_NRings(b.geom), a.corners_utm = b.corners_utm AND a.swath = b.swath "
            "AND a.index_in_swath = b.index_in_swath AND a.area_m2 = b.area_m2, ST_SRID(b.geom) "
            "FROM t_a a JOIN t_b b USING (seq) ORDER BY seq"
        )
    ).all()
    assert len(rows) == n
    for seq_, _eq, hd, _nr, same, srid in rows:
        assert hd < 1e-12 and same and srid == 4326, seq_
    assert rows[-1][3] == 2  # the holed cell kept its hole
    db.rollback()


def test_load_cell_table_round_trip(db, org) -> None:
    from fieldrx.db.models import Plan
    from fieldrx.services.plans import driver_connection, fast_cell_copy_payloads, load_cell_table

    polys, corners = _cells()
    n = len(polys)
    pid = _plan(db, org.id)  # the trigger made its partition
    seq = np.arange(n)[::-1].copy()  # stored out of order: the reader sorts by seq
    conn = driver_connection(db)
    with (
        conn.cursor() as cur,
        cur.copy(
            "COPY plan_cells (plan_id, seq, swath, index_in_swath, area_m2, corners_utm, geom) "
            "FROM STDIN (FORMAT BINARY)"
        ) as cp,
    ):
        for chunk in fast_cell_copy_payloads(
            pid, seq, seq // 3, seq % 3, shapely.area(polys), corners, polys, EPSG
        ):
            cp.write(chunk)
    table = load_cell_table(db, db.get(Plan, pid), EPSG)
    assert table.seq.tolist() == list(range(n))
    order = np.argsort(seq)
    for i, j in enumerate(order):
        assert table.polygons_utm[i].symmetric_difference(polys[j]).area < 1e-6
        assert table.polygons_utm[i].contains(shapely.Point(table.centroids_utm[i])) or (
            table.polygons_utm[i].distance(shapely.Point(table.centroids_utm[i])) < 1e-9
        )
        assert table.centroids_utm[i] == pytest.approx(
            np.asarray(polys[j].centroid.coords[0]), abs=1e-3
        ) or len(polys[j].interiors)
    assert np.allclose(table.corners_utm, corners[order])
    assert np.allclose(table.area_m2, shapely.area(polys)[order])
    assert table.swath.tolist() == (np.arange(n) // 3).tolist()
    wgs = table.polygons_wgs84()
    assert abs(wgs[0].centroid.x - 112.3) < 0.1
    db.rollback()
