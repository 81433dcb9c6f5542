"""The cell store: plan cells written by binary COPY into their partition and read back
packed as the one cell type; a prescription version's rates."""

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


def _table(polys: np.ndarray, corners: np.ndarray, seq: np.ndarray | None = None):  # noqa: ANN202
    from fieldrx.geo.cells import Cells

    n = len(polys)
    seq = np.arange(n) if seq is None else seq
    return Cells(
        epsg=EPSG,
        seq=seq,
        swath=seq // 3,
        index_in_swath=seq % 3,
        corners_utm=corners,
        area_m2=shapely.area(polys),
        polygons_utm=polys,
    )


def _split_cell() -> shapely.MultiPolygon:
    """A cell a notch cut in two: both parts, no "largest part"."""
    return shapely.MultiPolygon(
        [
            shapely.box(X0 + 6, Y0 + 10, X0 + 8.3, Y0 + 12),
            shapely.box(X0 + 6, Y0 + 13, X0 + 8.3, Y0 + 15),
        ]
    )


def test_payload_writes_every_geometry_exactly(db, org) -> None:
    """The numpy EWKB path (one-ring cells) and the shapely path (holes, split cells)
    store the same lon/lat geometry the cell type's WGS84 view has."""
    from fieldrx.store.cells import PLAN_CELLS, cell_payload, driver_connection

    polys, corners = _cells()
    polys = np.append(polys, _split_cell())
    corners = np.concatenate([corners, corners[-1:]])
    cells = _table(polys, corners)
    conn = driver_connection(db)
    with conn.cursor() as cur:
        cur.execute("CREATE TEMP TABLE t_a (LIKE plan_cells INCLUDING CONSTRAINTS)")
        PLAN_CELLS.write_payload(cur, cell_payload(7, cells), "t_a")
    rows = db.execute(
        text(
            "SELECT seq, ST_AsBinary(geom), ST_SRID(geom), corners_utm, swath, index_in_swath,"
            " area_m2 FROM t_a ORDER BY seq"
        )
    ).all()
    assert [r[0] for r in rows] == list(range(len(polys)))
    want = cells.polygons_wgs84()
    for r in rows:
        got = shapely.from_wkb(bytes(r[1]))
        assert got.geom_type == want[r[0]].geom_type, r[0]
        assert shapely.hausdorff_distance(got, want[r[0]]) < 1e-12, r[0]
        assert r[2] == 4326
        assert np.allclose(np.reshape(r[3], (4, 2)), corners[r[0]])
        assert (r[4], r[5], r[6]) == (r[0] // 3, r[0] % 3, pytest.approx(polys[r[0]].area))
    assert shapely.from_wkb(bytes(rows[-2][1])).interiors  # the holed cell kept its hole
    assert len(shapely.from_wkb(bytes(rows[-1][1])).geoms) == 2  # the split cell: both parts
    db.rollback()


def test_write_and_load_plan_cells_round_trip(db, org) -> None:
    """write_plan_cells (own partition, attached) then load_cells: path order, whole split
    cells, the one centre rule, UTM corners exact; a seq range reads a page."""
    from fieldrx.store import load_cells, load_seq_area, write_plan_cells

    polys, corners = _cells()
    polys = np.append(polys, _split_cell())
    corners = np.concatenate([corners, corners[-1:]])
    n = len(polys)
    db.execute(text("SELECT set_config('fieldrx.bulk_plan_cells', 'on', true)"))
    pid = _plan(db, org.id)
    db.execute(text("SELECT set_config('fieldrx.bulk_plan_cells', 'off', true)"))
    seq = np.arange(n)[::-1].copy()  # written out of order: the reader sorts by seq
    order = np.argsort(seq)
    times = write_plan_cells(db, pid, _table(polys, corners, seq))
    assert set(times) == {"payload_s", "copy_s", "index_attach_s"}
    cells = load_cells(db, pid, EPSG)
    assert cells.seq.tolist() == list(range(n))
    for i, j in enumerate(order):
        assert cells.polygons_utm[i].symmetric_difference(polys[j]).area < 1e-6
        assert cells.polygons_utm[i].geom_type == polys[j].geom_type
    np.testing.assert_allclose(cells.corners_utm, corners[order])
    np.testing.assert_allclose(cells.index_in_swath, seq[order] % 3)
    # the one centre rule: area centroid, or a point on the surface when it falls outside
    for i, j in enumerate(order):
        c = shapely.Point(cells.centroids_utm[i])
        assert polys[j].intersects(c.buffer(1e-9)), i
        if polys[j].contains(polys[j].centroid):
            assert c.distance(polys[j].centroid) < 1e-6
    page = load_cells(db, pid, EPSG, 2, 5)
    assert page.seq.tolist() == [2, 3, 4]
    assert page.polygons_wgs84()[0].equals_exact(cells.polygons_wgs84()[2], 1e-12)
    s2, a2 = load_seq_area(db, pid)
    assert s2.tolist() == list(range(n))
    np.testing.assert_allclose(a2, shapely.area(polys[order]))
    db.rollback()


def test_write_refuses_non_polygonal_cell(db, org) -> None:
    from fieldrx.store import write_plan_cells

    polys, corners = _cells()
    polys = polys.copy()
    polys[3] = shapely.LineString([(X0, Y0), (X0 + 1, Y0)])
    with pytest.raises(ValueError, match="cell seq 3 is a LineString"):
        write_plan_cells(db, 1, _table(polys, corners))
    db.rollback()


def test_rates_round_trip(db, org) -> None:
    """write_rates / load_rates: flags as names in, bits out; NaN source = NULL; a range."""
    from fieldrx.agronomy.cells import FLAG_BITS
    from fieldrx.db.models import Prescription, PrescriptionVersion
    from fieldrx.store import load_rates, write_rates

    pid = _plan(db, org.id)
    rx = Prescription(organisation_id=org.id, plan_id=pid, name="r", model="uniform", params={})
    db.add(rx)
    db.flush()
    ver = PrescriptionVersion(prescription_id=rx.id, version=1, note="", summary={})
    db.add(ver)
    db.flush()
    n = 9
    seq = np.arange(n)[::-1].copy()
    rate = np.linspace(100.0, 180.0, n)
    flags = np.array([0, 1, 2, 4, 8, 16, 1 | 8, 2 | 16, 0], np.uint16)
    src = np.where(np.arange(n) % 2 == 0, np.nan, np.arange(n) * 1.5)
    write_rates(db, ver.id, seq, rate, flags, src)
    names = db.execute(
        text("SELECT flags FROM prescription_rates WHERE version_id = :v AND seq = :s"),
        {"v": ver.id, "s": int(seq[6])},
    ).scalar()
    assert names == ["no_data", "manual"]
    s, r, f, v = load_rates(db, ver.id)
    order = np.argsort(seq)
    assert s.tolist() == list(range(n))
    np.testing.assert_array_equal(r, rate[order])
    np.testing.assert_array_equal(f, flags[order])
    np.testing.assert_array_equal(np.isnan(v), np.isnan(src[order]))
    np.testing.assert_array_equal(v[~np.isnan(v)], src[order][~np.isnan(src[order])])
    assert (f & FLAG_BITS["zone"]).sum() > 0
    s3, *_ = load_rates(db, ver.id, 3, 6)
    assert s3.tolist() == [3, 4, 5]
    with pytest.raises(ValueError, match="no finite rate"):
        write_rates(db, ver.id, seq, np.full(n, np.nan), flags, None)
    db.rollback()
