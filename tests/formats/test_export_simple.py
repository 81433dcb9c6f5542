"""GeoJSON, Table 1 CSV and zipped Shapefile exports read back with independent readers."""

import csv
import io
import json
import zipfile

import numpy as np
import pytest
import shapefile as pyshp
import shapely
from fieldrx.agronomy.cells import flag_strings
from fieldrx.formats.csv_table import HEADER, write_table1_csv
from fieldrx.formats.geojson import write_geojson
from fieldrx.formats.shapefile import write_shapefile_zip
from shapely.geometry import shape


def _same_geom(a, b, tol_deg=2e-9):
    # symmetric difference area relative to the cell, and Hausdorff in degrees
    assert shapely.hausdorff_distance(a, b) < tol_deg
    assert abs(a.area - b.area) <= 2e-9 * a.length  # 1e-9 deg rounding of every vertex


def test_geojson_roundtrip(cells):
    fc = json.loads(write_geojson(cells, {"prescription_id": 3, "version": 2}))
    assert fc["type"] == "FeatureCollection" and fc["properties"]["version"] == 2
    assert len(fc["features"]) == len(cells)
    polys = cells.polygons_wgs84()
    flags = flag_strings(cells.flags)
    for i, f in enumerate(fc["features"]):
        p = f["properties"]
        assert p["seq"] == cells.seq[i] and p["rate_kg_ha"] == pytest.approx(cells.rate_kg_ha[i])
        assert p["unit"] == "kg/ha" and p["flag"] == flags[i]
        _same_geom(shape(f["geometry"]), polys[i])


def test_table1_csv_roundtrip(cells):
    rows = list(csv.reader(io.StringIO(write_table1_csv(cells).decode())))
    assert rows[0] == HEADER
    assert rows[0][:3] == ["cell_id", "lat1", "lon1"] and rows[0][-1] == "rate_kg_ha"
    body = rows[1:]
    assert len(body) == len(cells)
    seq = np.array([int(r[0]) for r in body])
    np.testing.assert_array_equal(seq, cells.seq)  # path order kept
    vals = np.array([[float(v) for v in r[1:]] for r in body])
    lat = vals[:, 0:8:2]
    lon = vals[:, 1:8:2]
    np.testing.assert_allclose(lat, cells.corners_wgs84[:, :, 1], atol=1e-9)
    np.testing.assert_allclose(lon, cells.corners_wgs84[:, :, 0], atol=1e-9)
    np.testing.assert_allclose(vals[:, 8], cells.rate_kg_ha, atol=0.005)
    # corners counter-clockwise (positive signed area in lon/lat)
    x, y = lon, lat
    signed = 0.5 * np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)
    assert (signed > 0).all()


def test_shapefile_zip_roundtrip(cells):
    data = write_shapefile_zip(cells, "rx")
    z = zipfile.ZipFile(io.BytesIO(data))
    names = sorted(z.namelist())
    assert names == ["rx.cpg", "rx.dbf", "rx.prj", "rx.shp", "rx.shx"]  # flat, no folder
    assert "WGS_1984" in z.read("rx.prj").decode()
    r = pyshp.Reader(
        shp=io.BytesIO(z.read("rx.shp")),
        shx=io.BytesIO(z.read("rx.shx")),
        dbf=io.BytesIO(z.read("rx.dbf")),
    )
    assert r.shapeType == pyshp.POLYGON and len(r) == len(cells)
    fields = {f[0]: f for f in r.fields[1:]}
    assert fields["RATE"][1] == "N" and fields["UNIT"][1] == "C"
    polys = cells.polygons_wgs84()
    for i, sr in enumerate(r.iterShapeRecords()):
        rec = sr.record
        assert rec["SEQ"] == cells.seq[i]
        assert isinstance(rec["RATE"], float) and rec["RATE"] == pytest.approx(
            cells.rate_kg_ha[i], abs=0.005
        )
        assert rec["UNIT"] == "kg/ha"
        _same_geom(shape(sr.shape.__geo_interface__), polys[i])


def test_shapefile_multipart_cell_with_hole():
    from fieldrx.agronomy.cells import CellTable

    EPSG, X0, Y0 = 32649, 624000.0, 3556000.0

    a = shapely.box(X0, Y0, X0 + 10, Y0 + 10).difference(
        shapely.box(X0 + 4, Y0 + 4, X0 + 6, Y0 + 6)
    )
    b = shapely.box(X0 + 20, Y0, X0 + 22, Y0 + 5)
    cells = CellTable.from_polygons_utm(
        EPSG, np.array([0]), np.array([0]), np.array([shapely.union_all([a, b])])
    )
    cells = cells.with_rates(np.array([432.1]))
    z = zipfile.ZipFile(io.BytesIO(write_shapefile_zip(cells)))
    r = pyshp.Reader(
        shp=io.BytesIO(z.read("prescription.shp")),
        shx=io.BytesIO(z.read("prescription.shx")),
        dbf=io.BytesIO(z.read("prescription.dbf")),
    )
    got = shape(r.shape(0).__geo_interface__)
    assert got.geom_type == "MultiPolygon" and len(got.geoms) == 2
    _same_geom(got, cells.polygons_wgs84()[0])
    assert r.record(0)["RATE"] == pytest.approx(432.1)
