"""The acceptance test: exports read by isoxml-js (npm ``isoxml``, dev4Agriculture), a second
independent ISOXML reader besides isoxml-py, with the whole area and the same rates.

``js/read_taskdata.js`` parses the TASKDATA zip with isoxml-js and prints the grid cells
and treatment zones it found as JSON; installed by ``scripts/setup.sh --test``
(``npm ci`` in tests/formats/js).
"""

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import shapely
from fieldrx.formats.isoxml import rate_to_mg_m2, write_isoxml_grid, write_isoxml_zones

from tests.formats.test_zones import field_cells, geod_area
from tests.support import scaled

JS = Path(__file__).parent / "js"


def read_with_isoxml_js(data: bytes, tmp_path: Path) -> dict:
    node = shutil.which("node")
    assert node, "node is not installed (scripts/setup.sh)"
    assert (JS / "node_modules" / "isoxml").is_dir(), (
        "isoxml-js is not installed: run scripts/setup.sh --test (npm ci in tests/formats/js)"
    )
    z = tmp_path / "TASKDATA.zip"
    z.write_bytes(data)
    out = subprocess.run(
        [node, str(JS / "read_taskdata.js"), str(z)], capture_output=True, timeout=scaled(300)
    )
    assert out.returncode == 0, out.stderr.decode()
    return json.loads(out.stdout)


@pytest.mark.parametrize("kind", ["smooth", "random"])
def test_zone_taskdata_read_by_isoxml_js(kind, tmp_path):
    c = field_cells(kind)
    data, summary = write_isoxml_zones(c, "wavy", None, "urea")
    got = read_with_isoxml_js(data, tmp_path)
    assert got["warnings"] == []
    zones = [z for z in got["zones"] if z["geometry"] is not None]
    assert {z["code"] for z in got["zones"]} == set(range(len(zones) + 1))  # 0 = no rate
    assert len(zones) == summary.n_zones
    geoms = [shapely.geometry.shape(z["geometry"]) for z in zones]
    assert sum(len(g.geoms) for g in geoms) == summary.n_polygons <= 100
    assert all(g.is_valid for g in geoms)
    # the whole cell area, no zone lost (zero-rate area from unreadable zones: 0 m2)
    assert geod_area(geoms) == pytest.approx(geod_area(c.polygons_wgs84()), rel=1e-5)
    assert all(z["ddi"] == "0006" and z["value"] > 0 for z in zones)
    # every cell's centre lies in a zone whose setpoint is the cell's rate within the
    # largest change the export reported
    pts = shapely.point_on_surface(c.polygons_wgs84())
    cell_i, zone_i = shapely.STRtree(geoms).query(pts, predicate="intersects")
    assert np.array_equal(np.unique(cell_i), np.arange(len(c)))
    value = np.array([zones[k]["value"] for k in zone_i])
    want = rate_to_mg_m2(c.rate_kg_ha[cell_i])
    assert np.abs(value - want).max() <= summary.max_rate_change_kg_ha * 100 + 1


def test_grid_taskdata_read_by_isoxml_js(tmp_path):
    c = field_cells("smooth")
    got = read_with_isoxml_js(write_isoxml_grid(c, "wavy", None, "urea"), tmp_path)
    # isoxml-js looks for "GRD00001.bin" and warns that the file is "GRD00001.BIN" (the
    # name ISO 11783-10 and isoxml-py use); it reads it all the same
    assert all("GRD00001.BIN" in w for w in got["warnings"])
    g = got["grid"]
    cells = np.asarray(g["cells"], dtype=float)
    assert len(cells) > 0
    # area: the valued grid cells cover the field (grid cells are 2.3 m x 5 m scale)
    lon0, lat0 = cells[:, 0].mean(), cells[:, 1].mean()
    from pyproj import Geod

    geod = Geod(ellps="WGS84")
    ew = geod.inv(lon0, lat0, lon0 + g["cell_east"], lat0)[2]
    ns = geod.inv(lon0, lat0, lon0, lat0 + g["cell_north"])[2]
    field = geod_area(c.polygons_wgs84())
    assert len(cells) * ew * ns == pytest.approx(field, rel=0.03)
    # rates: each valued centre inside a cell carries that cell's rate (mg/m2)
    polys = c.polygons_wgs84()
    pts = shapely.points(cells[:, 0], cells[:, 1])
    pi, ci = shapely.STRtree(polys).query(pts, predicate="within")
    assert len(pi) > 0.9 * len(cells)
    want = rate_to_mg_m2(c.rate_kg_ha[ci])
    assert np.array_equal(cells[pi, 2].astype(np.int64), np.asarray(want, dtype=np.int64))


def test_seeds_per_ha_zones_read_by_isoxml_js(tmp_path):
    """A seeding prescription's zones carry count-per-area setpoints (DDI 11, 0.001 /m^2):
    isoxml-js reads DDI 000B with seeds/ha / 10 (a maize lot: TKW 320 g, 95 %)."""
    from fieldrx.formats.isoxml import unit_setpoint

    lot = {"tkw_g": 320.0, "germination_pct": 95.0}
    setpoint = unit_setpoint("seeds/ha", lot)
    c = field_cells("smooth")
    seeds = 60_000 + 30_000 * (c.rate_kg_ha - c.rate_kg_ha.min()) / np.ptp(c.rate_kg_ha)
    c = c.with_rates(seeds * setpoint.kg_per_unit)
    data, summary = write_isoxml_zones(c, "wavy", None, "maize", setpoint=setpoint)
    got = read_with_isoxml_js(data, tmp_path)
    assert got["warnings"] == []
    zones = [z for z in got["zones"] if z["geometry"] is not None]
    assert len(zones) == summary.n_zones and all(z["ddi"] == "000B" for z in zones)
    values = np.array([z["value"] for z in zones])
    assert 6_000 - 1 <= values.min() and values.max() <= 9_000 + 1
