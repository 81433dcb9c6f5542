"""Every export downloads and reads back (independent readers) to the same rates; rx tiles."""

from __future__ import annotations

import csv
import io
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest
import shapefile as pyshp
import shapely
import xmlschema
from isoxml.converter.np_grid import to_numpy_array
from isoxml.converter.shapely_geom import ShapelyConverterV4
from isoxml.util.isoxml_io import isoxml_from_path
from shapely.geometry import shape

from tests.support.mvt import decode, lonlat_to_tile
from tests.support.plans import API
from tests.support.prescriptions import FIELD, all_cells, make_rx, samples_csv, setup_plan

XSD = Path("/work/shared/isoxml-xsd/ISO11783_TaskFile_V4-3.xsd")


@pytest.fixture(scope="module")
def schema():
    return xmlschema.XMLSchema(str(XSD))


@pytest.fixture()
def rx(client, org):
    """A variable-rate prescription (kriging over an N gradient) with one manual edit (v2)."""
    h = org.headers()
    plan = setup_plan(client, h, samples_csv(grid=4), swath_width_m=4, cell_length_m=5)
    r = make_rx(
        client,
        h,
        plan["id"],
        name="Rape N / spring",
        model="nutrient_balance",
        params={"target_yield_kg_ha": 2500, "n_fraction": 0.25},
        interpolation="idw",
    )
    e = client.post(
        f"{API}/prescriptions/{r['id']}/edits",
        headers=h,
        json={"cells": [{"seq": 1, "rate_kg_ha": 321.5}]},
    )
    assert e.status_code == 201
    cells = all_cells(client, h, r["id"])
    return {
        "id": r["id"],
        "h": h,
        "cells": cells,
        "plan": plan,
        "rates": {c["properties"]["seq"]: c["properties"]["rate_kg_ha"] for c in cells},
    }


def _get(client, rx, fmt, version=None):
    q = f"?format={fmt}" + (f"&version={version}" if version else "")
    r = client.get(f"{API}/prescriptions/{rx['id']}/export{q}", headers=rx["h"])
    assert r.status_code == 200, r.text
    assert r.headers["content-disposition"].startswith("attachment; filename=")
    return r


def test_geojson_export(client, rx) -> None:
    r = _get(client, rx, "geojson")
    assert r.headers["content-type"].startswith("application/geo+json")
    # named by field, product and date, then prescription and version (not the model)
    stem = _stem(client, rx)
    assert f'filename="{stem}.geojson"' in r.headers["content-disposition"]
    fc = json.loads(r.content)
    got = {f["properties"]["seq"]: f["properties"]["rate_kg_ha"] for f in fc["features"]}
    assert got == pytest.approx(rx["rates"], abs=1e-3)
    assert got[1] == 321.5
    for f, c in zip(fc["features"], rx["cells"], strict=True):
        assert shape(f["geometry"]).symmetric_difference(shape(c["geometry"])).area < 1e-12
    v1 = json.loads(_get(client, rx, "geojson", version=1).content)
    assert v1["properties"]["version"] == 1
    assert v1["features"][1]["properties"]["rate_kg_ha"] != 321.5


def test_csv_export_table1(client, rx) -> None:
    r = _get(client, rx, "csv")
    rows = list(csv.DictReader(io.StringIO(r.text)))
    assert list(rows[0])[:3] == ["cell_id", "lat1", "lon1"]
    assert {int(x["cell_id"]): float(x["rate_kg_ha"]) for x in rows} == pytest.approx(
        rx["rates"], abs=0.005
    )
    # the four corners enclose the clipped cell (uncut rectangle, lat/lon order)
    for x, c in zip(rows[:50], rx["cells"][:50], strict=True):
        quad = shapely.Polygon([(float(x[f"lon{i}"]), float(x[f"lat{i}"])) for i in range(1, 5)])
        assert shape(c["geometry"]).difference(quad.buffer(1e-7)).area < 1e-12


def _stem(client, rx) -> str:  # noqa: ANN001
    """What a version's files are called: field_product_YYYYMMDD_rx<id>v<version>."""
    import re

    got = client.get(f"{API}/prescriptions/{rx['id']}", headers=rx["h"]).json()
    fld = client.get(f"{API}/fields/{rx['plan']['field_id']}", headers=rx["h"]).json()
    ver = client.get(f"{API}/prescriptions/{rx['id']}/versions/2", headers=rx["h"]).json()

    def slug(x: str) -> str:
        return re.sub(r"[^A-Za-z0-9-]+", "_", x).strip("_")

    day = ver["created_at"][:10].replace("-", "")
    product = slug(got["product"] or "fertilizer")
    return f"{slug(fld['properties']['name'])}_{product}_{day}_rx{rx['id']}v2"


def test_terminal_profiles_name_files_per_version(client, rx) -> None:
    """Every terminal profile names its files after the version (a Deere Rx/ folder holding
    two prescriptions kept only the last: both were Rx/prescription.shp)."""
    stem = _stem(client, rx)
    for profile in ("cells", "deere", "fieldview", "raven", "agleader", "trimble"):
        r = client.get(
            f"{API}/prescriptions/{rx['id']}/export?format=shapefile&profile={profile}",
            headers=rx["h"],
        )
        assert r.status_code == 200, r.text
        names = zipfile.ZipFile(io.BytesIO(r.content)).namelist()
        folder = "Rx/" if profile == "deere" else ""
        assert f"{folder}{stem}.shp" in names, (profile, names)
        assert stem in r.headers["content-disposition"]


def test_shapefile_export(client, rx) -> None:
    r = _get(client, rx, "shapefile")
    z = zipfile.ZipFile(io.BytesIO(r.content))
    names = z.namelist()
    assert all("/" not in n for n in names)  # flat zip
    stem = next(n for n in names if n.endswith(".shp"))[:-4]
    assert stem == _stem(client, rx)
    assert {f"{stem}.{e}" for e in ("shp", "shx", "dbf", "prj")} <= set(names)
    rd = pyshp.Reader(
        shp=io.BytesIO(z.read(f"{stem}.shp")),
        shx=io.BytesIO(z.read(f"{stem}.shx")),
        dbf=io.BytesIO(z.read(f"{stem}.dbf")),
    )
    got = {}
    for sr in rd.iterShapeRecords():
        rec = sr.record.as_dict()
        assert rec["UNIT"] == "kg/ha"
        got[rec["SEQ"]] = rec["RATE"]
        ref = shape(rx["cells"][rec["SEQ"]]["geometry"])
        assert (
            shape(sr.shape.__geo_interface__).symmetric_difference(ref).area
            < 1e-6 * ref.area + 1e-14
        )
    assert got == pytest.approx(rx["rates"], abs=0.005)


def _unpack(data: bytes, tmp_path: Path) -> Path:
    zipfile.ZipFile(io.BytesIO(data)).extractall(tmp_path)
    return tmp_path / "TASKDATA"


def test_isoxml_grid_export(client, rx, schema, tmp_path) -> None:
    r = _get(client, rx, "isoxml")
    assert r.headers["content-type"] == "application/zip"
    d = _unpack(r.content, tmp_path)
    schema.validate(str(d / "TASKDATA.XML"))
    td, refs = isoxml_from_path(d)
    grd = td.tasks[0].grids[0]
    arr = to_numpy_array(refs["GRD00001"], grd)
    lat0, lon0 = float(grd.minimum_north_position), float(grd.minimum_east_position)
    polys = [shape(c["geometry"]) for c in rx["cells"]]
    tree = shapely.STRtree(polys)
    rates = np.array([c["properties"]["rate_kg_ha"] for c in rx["cells"]])
    inside = 0
    rows, cols = arr.shape
    for i in range(rows):
        for j in range(cols):
            p = shapely.Point(
                lon0 + (j + 0.5) * grd.cell_east_size, lat0 + (i + 0.5) * grd.cell_north_size
            )
            hits = tree.query(p, predicate="intersects")
            if len(hits):
                inside += 1
                assert arr[i, j] in {int(round(rates[k] * 100)) for k in hits}
    assert inside > 50
    # every cell larger than a grid cell shows its rate somewhere (mg/m2 = 100 x kg/ha)
    big = np.array([c["properties"]["area_m2"] for c in rx["cells"]]) >= 10.0
    assert {int(round(v * 100)) for v in rates[big]} <= set(np.unique(arr).tolist())


def test_isoxml_zones_export(client, rx, schema, tmp_path) -> None:
    r = _get(client, rx, "isoxml-zones")
    d = _unpack(r.content, tmp_path)
    schema.validate(str(d / "TASKDATA.XML"))
    td, _ = isoxml_from_path(d)
    conv = ShapelyConverterV4()
    zones = []
    for t in td.tasks[0].treatment_zones:
        if t.polygons:
            g = shapely.union_all([conv.to_shapely_polygon(p) for p in t.polygons])
            zones.append((g, t.process_data_variables[0].process_data_value))
    # cells dissolved into rate classes: every cell in exactly one zone, and the
    # rate change the dissolving made is reported, never silent
    info = json.loads(r.headers["X-FieldRx-Zones"])
    assert "rate zones" in r.headers["X-FieldRx-Export-Note"]
    assert len(zones) <= info["n_zones"] <= 8 and info["n_polygons"] <= 100
    tree = shapely.STRtree([z[0] for z in zones])
    for c in rx["cells"]:
        pt = shape(c["geometry"]).representative_point()
        hits = tree.query(pt, predicate="intersects")
        assert len(hits) == 1
        want = c["properties"]["rate_kg_ha"] * 100
        assert abs(zones[hits[0]][1] - want) <= info["max_rate_change_kg_ha"] * 100 + 1


def test_export_errors(client, rx, make_org) -> None:
    bad = client.get(f"{API}/prescriptions/{rx['id']}/export?format=pdf", headers=rx["h"])
    assert bad.status_code == 422
    missing = client.get(f"{API}/prescriptions/{rx['id']}/export?version=9", headers=rx["h"])
    assert missing.status_code == 404
    other = make_org()
    r = client.get(f"{API}/prescriptions/{rx['id']}/export?format=csv", headers=other.headers())
    assert r.status_code == 404


def test_prescription_tiles(client, rx) -> None:
    (lon0, lat0), (lon1, lat1) = FIELD["coordinates"][0][0], FIELD["coordinates"][0][2]
    x, y = lonlat_to_tile((lon0 + lon1) / 2, (lat0 + lat1) / 2, 20)
    url = f"{API}/tiles/prescriptions/{rx['id']}/2/20/{x}/{y}.mvt"
    r = client.get(url, headers=rx["h"])
    assert (
        r.status_code == 200 and r.headers["content-type"] == "application/vnd.mapbox-vector-tile"
    )
    feats = decode(r.content)["cells"]["features"]
    assert feats
    for f in feats:
        p = f["properties"]
        assert set(p) >= {"seq", "rate_kg_ha", "flags", "clamped"}
        assert p["rate_kg_ha"] == pytest.approx(rx["rates"][p["seq"]])
    one = [f for f in feats if f["properties"]["seq"] == 1]
    if one:
        assert one[0]["properties"]["flags"] == "manual"
    # version 1 tile differs for seq 1; unknown version -> 404
    r1 = client.get(f"{API}/tiles/prescriptions/{rx['id']}/1/20/{x}/{y}.mvt", headers=rx["h"])
    assert r1.status_code == 200 and r1.headers["etag"] != r.headers["etag"]
    assert (
        client.get(
            f"{API}/tiles/prescriptions/{rx['id']}/7/20/{x}/{y}.mvt", headers=rx["h"]
        ).status_code
        == 404
    )
    # overview zoom: binned, rate is a mean within the prescription's range
    x, y = lonlat_to_tile((lon0 + lon1) / 2, (lat0 + lat1) / 2, 14)
    r = client.get(f"{API}/tiles/prescriptions/{rx['id']}/2/14/{x}/{y}.mvt", headers=rx["h"])
    feats = decode(r.content)["cells"]["features"]
    lo, hi = min(rx["rates"].values()), max(rx["rates"].values())
    assert feats and all(lo - 1e-6 <= f["properties"]["rate_kg_ha"] <= hi + 1e-6 for f in feats)
