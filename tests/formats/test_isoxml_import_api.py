"""ISOXML import: preview then confirm, round trip of FieldRx's own exports."""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest
import shapely
from shapely.geometry import shape

from tests.plans.helpers import API, make_field, make_plan
from tests.prescriptions.helpers import FIELD, all_cells, make_rx, samples_csv


def holed_field() -> dict:
    ring = FIELD["coordinates"][0]
    (lon0, lat0), (lon1, lat1) = ring[0], ring[2]
    cx, cy, dx, dy = (lon0 + lon1) / 2, (lat0 + lat1) / 2, (lon1 - lon0) / 8, (lat1 - lat0) / 8
    hole = [
        [cx - dx, cy - dy],
        [cx - dx, cy + dy],
        [cx + dx, cy + dy],
        [cx + dx, cy - dy],
        [cx - dx, cy - dy],
    ]
    return {"type": "Polygon", "coordinates": [ring, hole]}


@pytest.fixture()
def rx(client, org):
    h = org.headers()
    fid = make_field(client, h, holed_field(), name="Pond field")
    r = client.post(
        f"{API}/fields/{fid}/soil-samples",
        headers=h,
        files={"file": ("s.csv", samples_csv(grid=4), "text/csv")},
    )
    assert r.status_code == 201, r.text
    plan = make_plan(client, h, fid, swath_width_m=4, cell_length_m=5)
    r = make_rx(
        client,
        h,
        plan["id"],
        name="N spring",
        model="nutrient_balance",
        params={"target_yield_kg_ha": 2500, "n_fraction": 0.25},
        interpolation="idw",
    )
    field = client.get(f"{API}/fields/{fid}", headers=h).json()
    return {"id": r["id"], "h": h, "field": field, "cells": all_cells(client, h, r["id"])}


def _count(client, h, what):
    return client.get(f"{API}/{what}", headers=h).json()["total"]


def _import(client, h, data: bytes, name="TASKDATA.zip", **q):
    files = {"files": (name, data, "application/zip")}
    qs = "&".join(f"{k}={v}" for k, v in q.items())
    return client.post(f"{API}/imports/isoxml?{qs}", headers=h, files=files)


@pytest.mark.parametrize("fmt", ["isoxml", "isoxml-zones"])
def test_own_export_round_trips(client, rx, fmt):
    h = rx["h"]
    exp = client.get(f"{API}/prescriptions/{rx['id']}/export?format={fmt}", headers=h)
    assert exp.status_code == 200
    n_fields = _count(client, h, "fields")
    pre = _import(client, h, exp.content, swath_width_m=4, cell_length_m=5)
    assert pre.status_code == 200, pre.text
    body = pre.json()
    assert body["stored"] is False and _count(client, h, "fields") == n_fields  # nothing stored
    (f,) = body["preview"]["fields"]
    assert f["holes"] == 1
    (p,) = body["preview"]["prescriptions"]
    assert p["unit"] == "kg/ha" and p["ddi"] == 6
    assert p["kind"] == ("grid type 2" if fmt == "isoxml" else "zones")
    bad = _import(client, h, exp.content, confirm="0" * 64)
    assert bad.status_code == 409 and _count(client, h, "fields") == n_fields
    ok = _import(client, h, exp.content, confirm=body["sha256"], swath_width_m=4, cell_length_m=5)
    assert ok.status_code == 201, ok.text
    created = ok.json()["created"]
    fid = created["fields"][0]["id"]
    new_field = client.get(f"{API}/fields/{fid}", headers=h).json()
    a0 = rx["field"]["properties"]["area_m2"]
    assert new_field["properties"]["area_m2"] == pytest.approx(a0, rel=1e-4)  # within 0.01 %
    g0, g1 = shape(rx["field"]["geometry"]), shape(new_field["geometry"])
    assert shapely.symmetric_difference(g0, g1).area < 1e-4 * g0.area
    new_rx = created["prescriptions"][0]["id"]
    got = {
        c["properties"]["seq"]: c["properties"]["rate_kg_ha"] for c in all_cells(client, h, new_rx)
    }
    want = {c["properties"]["seq"]: c["properties"]["rate_kg_ha"] for c in rx["cells"]}
    assert set(got) == set(want)  # same plan parameters on the same boundary: the same cells
    diff = np.array([abs(got[s] - want[s]) for s in want])
    if fmt == "isoxml":
        # the same rate per cell (0.01 kg/ha resolution); cells smaller than a few grid cells
        # may take the rate of the neighbour under most of their grid centres
        area = np.array([c["properties"]["area_m2"] for c in rx["cells"]])
        off = diff > 0.005
        few_grid_cells = np.median(area)  # 4 grid cells: the default grid cell is half a side
        assert off.mean() < 0.02 and (area[off] < few_grid_cells).all(), (off.sum(), area[off])
    else:
        zones = json.loads(exp.headers["X-FieldRx-Zones"])
        assert diff.max() <= zones["max_rate_change_kg_ha"] + 0.01  # the zone's rate per cell
    info = client.get(f"{API}/prescriptions/{new_rx}", headers=h).json()
    assert info["model"] == "imported"


def test_taskdata_zip_to_field_import_points_to_isoxml(client, rx):
    exp = client.get(f"{API}/prescriptions/{rx['id']}/export?format=isoxml", headers=rx["h"])
    r = client.post(
        f"{API}/fields/import",
        headers=rx["h"],
        files={"file": ("TASKDATA.zip", exp.content, "application/zip")},
    )
    assert r.status_code == 422
    assert "/api/v1/imports/isoxml" in r.json()["detail"]
    assert "exactly one .shp" not in r.json()["detail"]


def test_loose_files_accepted(client, rx):
    exp = client.get(f"{API}/prescriptions/{rx['id']}/export?format=isoxml", headers=rx["h"])
    z = zipfile.ZipFile(io.BytesIO(exp.content))
    files = [
        ("files", (n.split("/")[-1], z.read(n), "application/octet-stream")) for n in z.namelist()
    ]
    r = client.post(f"{API}/imports/isoxml", headers=rx["h"], files=files)
    assert r.status_code == 200, r.text
    assert r.json()["preview"]["prescriptions"][0]["kind"] == "grid type 2"
