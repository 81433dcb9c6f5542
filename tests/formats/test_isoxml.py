"""ISO 11783-10 exports: XSD-valid, and read back by the `isoxml` package to the same rates."""

import io
import zipfile
from pathlib import Path

import numpy as np
import pytest
import shapely
import xmlschema
from fieldrx.formats.isoxml import (
    grid_spec,
    rate_to_mg_m2,
    write_isoxml_grid,
    write_isoxml_zones,
)
from isoxml.converter.np_grid import to_numpy_array
from isoxml.converter.shapely_geom import ShapelyConverterV4
from isoxml.util.isoxml_io import isoxml_from_path
from pyproj import Geod

XSD = Path("/work/shared/isoxml-xsd/ISO11783_TaskFile_V4-3.xsd")


@pytest.fixture(scope="module")
def schema():
    return xmlschema.XMLSchema(str(XSD))


def _unpack(data, tmp_path):
    z = zipfile.ZipFile(io.BytesIO(data))
    assert all(n.startswith("TASKDATA/") for n in z.namelist())
    z.extractall(tmp_path)
    return tmp_path / "TASKDATA"


def test_grid_export_valid_and_reads_back(cells, field_wgs84, schema, tmp_path):
    data = write_isoxml_grid(cells, "Test field", field_wgs84, "urea", grid_cell_m=1.0)
    d = _unpack(data, tmp_path)
    assert sorted(p.name for p in d.iterdir()) == ["GRD00001.BIN", "TASKDATA.XML"]
    schema.validate(str(d / "TASKDATA.XML"))  # raises on any violation
    task_data, refs = isoxml_from_path(d)
    task = task_data.tasks[0]
    grd = task.grids[0]
    assert grd.type.value == "2" and grd.treatment_zone_code == 1
    tzn = {t.code: t for t in task.treatment_zones}
    assert tzn[1].process_data_variables[0].process_data_ddi == bytes.fromhex("0006")
    arr = to_numpy_array(refs["GRD00001"], grd)
    assert arr.shape == (grd.maximum_row, grd.maximum_column)
    # cell size about 1 m at the field
    lat0, lon0 = float(grd.minimum_north_position), float(grd.minimum_east_position)
    g = Geod(ellps="WGS84")
    assert g.inv(lon0, lat0, lon0, lat0 + grd.cell_north_size)[2] == pytest.approx(1.0, rel=1e-3)
    assert g.inv(lon0, lat0, lon0 + grd.cell_east_size, lat0)[2] == pytest.approx(1.0, rel=1e-3)
    # independent check: row 0 is the south edge; each centre takes the rate of the covering cell
    polys = cells.polygons_wgs84()
    tree = shapely.STRtree(polys)
    rows, cols = arr.shape
    rng = np.random.default_rng(0)
    checked = inside = 0
    for r, c in zip(rng.integers(0, rows, 1500), rng.integers(0, cols, 1500), strict=True):
        lat = lat0 + (r + 0.5) * grd.cell_north_size
        lon = lon0 + (c + 0.5) * grd.cell_east_size
        hits = tree.query(shapely.Point(lon, lat), predicate="intersects")
        if len(hits) == 0:
            assert arr[r, c] == 0
        else:
            inside += 1
            assert arr[r, c] in {int(round(cells.rate_kg_ha[h] * 100)) for h in hits}
        checked += 1
    assert inside > 300
    # every prescription rate appears in the grid (mg/m^2 = 100 x kg/ha)
    big = cells.area_m2 > 4.0
    assert set(rate_to_mg_m2(cells.rate_kg_ha[big]).tolist()) <= set(np.unique(arr).tolist())
    # bounds: origin south-west of the field, grid covers it
    w, s, e, n = field_wgs84.bounds
    assert lat0 <= s and lon0 <= w
    assert lat0 + rows * grd.cell_north_size >= n and lon0 + cols * grd.cell_east_size >= e


def test_grid_row_zero_is_south(schema, tmp_path):
    from fieldrx.agronomy.cells import CellTable

    # two cells stacked north-south: south one 100 kg/ha, north one 200 kg/ha
    c = CellTable.rectangle(32649, 624000.0, 3556000.0, 1, 2, 10.0, 10.0).with_rates(
        np.array([100.0, 200.0])
    )
    d = _unpack(write_isoxml_grid(c, "stack", grid_cell_m=5.0), tmp_path)
    schema.validate(str(d / "TASKDATA.XML"))
    td, refs = isoxml_from_path(d)
    arr = to_numpy_array(refs["GRD00001"], td.tasks[0].grids[0])
    mid = arr.shape[1] // 2
    col = arr[:, mid]  # south -> north; 1 kg/ha = 100 mg/m^2
    assert col[1] == 10000 and col[-2] == 20000
    assert list(col[col > 0]) == sorted(col[col > 0])


def test_zones_export_valid_and_reads_back(cells, field_wgs84, schema, tmp_path):
    data, summary = write_isoxml_zones(
        cells, "Test field", field_wgs84, "urea", n_classes=254, max_polygons=5000, min_patch_m2=0
    )
    d = _unpack(data, tmp_path)
    schema.validate(str(d / "TASKDATA.XML"))
    text = (d / "TASKDATA.XML").read_text()
    assert "0.0000000001" not in text  # never more than 9 fraction digits
    td, _ = isoxml_from_path(d)
    conv = ShapelyConverterV4()
    zones = []
    for t in td.tasks[0].treatment_zones:
        pdv = t.process_data_variables[0]
        assert pdv.process_data_ddi == bytes.fromhex("0006")
        if t.polygons:
            geom = shapely.union_all([conv.to_shapely_polygon(p) for p in t.polygons])
            zones.append((geom, pdv.process_data_value))
    assert len(zones) == len(np.unique(rate_to_mg_m2(cells.rate_kg_ha)))
    tree = shapely.STRtree([z[0] for z in zones])
    pts = shapely.point_on_surface(cells.polygons_wgs84())
    for i, p in enumerate(pts):
        hits = tree.query(p, predicate="intersects")
        assert len(hits) >= 1
        assert {zones[h][1] for h in hits} == {int(round(cells.rate_kg_ha[i] * 100))}
    # the zones cover the cells' area (same geometry)
    zone_union = shapely.union_all([z[0] for z in zones])
    cell_union = shapely.union_all(cells.polygons_wgs84())
    assert shapely.symmetric_difference(zone_union, cell_union).area < 1e-4 * cell_union.area


def test_zones_quantised_when_too_many_rates(cells, schema, tmp_path):
    c = cells.with_rates(np.linspace(200.0, 800.0, len(cells)))
    d = _unpack(write_isoxml_zones(c, "many", n_classes=8)[0], tmp_path)
    schema.validate(str(d / "TASKDATA.XML"))
    td, _ = isoxml_from_path(d)
    codes = [t.code for t in td.tasks[0].treatment_zones]
    assert codes == list(range(9))  # 0 = no rate, 1..8 classes


def test_grid_spec_limits():
    s = grid_spec((112.0, 32.0, 112.001, 32.001), 1.0)
    assert s.rows > 100 and s.cols > 90
    assert f"{s.south:.9f}" == "32.000000000"


def test_task_name_cut_at_a_word_boundary():
    """ISO 11783-10 designators hold 32 characters: a long field name is cut between words
    (a terminal showed "Rx Home field north of the ba")."""
    from fieldrx.formats.isoxml import task_name

    assert (
        task_name("Rx Home field north of the barn by the river")
        == "Rx Home field north of the barn"
    )
    assert task_name("Rx short") == "Rx short"
    assert task_name("x" * 40) == "x" * 32  # one long word: cut where it must be
    assert all(len(task_name("a b " * k)) <= 32 for k in range(30))
