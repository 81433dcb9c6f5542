"""Prescription Shapefile import with attribute mapping, round trips."""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest
import shapefile as pyshp

from tests.formats.test_isoxml_import_api import rx  # noqa: F401  (fixture)
from tests.support.plans import API
from tests.support.prescriptions import all_cells


def _post(client, h, fid, data, **q):
    qs = "&".join(f"{k}={v}" for k, v in {"field_id": fid, **q}.items())
    return client.post(
        f"{API}/imports/prescription-shapefile?{qs}",
        headers=h,
        files={"file": ("rx_shp.zip", data, "application/zip")},
    )


@pytest.mark.parametrize("profile", ["cells", "deere"])
def test_own_shapefile_round_trips(client, rx, profile):  # noqa: F811
    h, fid = rx["h"], rx["field"]["id"]
    exp = client.get(
        f"{API}/prescriptions/{rx['id']}/export?format=shapefile&profile={profile}", headers=h
    )
    assert exp.status_code == 200
    pre = _post(client, h, fid, exp.content)
    assert pre.status_code == 200, pre.text
    body = pre.json()
    assert body["suggested_rate_column"] == "RATE" and "RATE" in body["numeric_columns"]
    assert body["stored"] is False
    no_map = _post(client, h, fid, exp.content, confirm=body["sha256"])
    assert no_map.status_code == 422 and "rate_column" in no_map.json()["detail"]
    ok = _post(
        client, h, fid, exp.content, rate_column="RATE", confirm=body["sha256"],
        swath_width_m=4, cell_length_m=5,
    )  # fmt: skip
    assert ok.status_code == 201, ok.text
    new_rx = ok.json()["created"]["prescription_id"]
    got = {
        c["properties"]["seq"]: c["properties"]["rate_kg_ha"] for c in all_cells(client, h, new_rx)
    }
    want = {c["properties"]["seq"]: c["properties"]["rate_kg_ha"] for c in rx["cells"]}
    assert set(got) == set(want)
    diff = np.array([abs(got[s] - want[s]) for s in want])
    if profile == "cells":
        assert diff.max() <= 0.0051  # the same rate per cell (2 decimals in the file)
    else:
        zones = json.loads(exp.headers["X-FieldRx-Zones"])
        assert diff.max() <= zones["max_rate_change_kg_ha"] + 0.01


def _shp(rates_lbac: list[float], field_geom) -> bytes:
    from shapely.geometry import shape

    g = shape(field_geom)
    w0, s0, e0, n0 = g.bounds
    mid = (w0 + e0) / 2
    boxes = [[(w0, s0), (w0, n0), (mid, n0), (mid, s0), (w0, s0)],
             [(mid, s0), (mid, n0), (e0, n0), (e0, s0), (mid, s0)]]  # fmt: skip
    shp, shx, dbf = io.BytesIO(), io.BytesIO(), io.BytesIO()
    with pyshp.Writer(shp=shp, shx=shx, dbf=dbf, shapeType=pyshp.POLYGON) as w:
        w.field("N_LBAC", "N", 10, 2)
        w.field("NOTE", "C", 10)
        for b, r in zip(boxes, rates_lbac, strict=True):
            w.poly([b])
            w.record(r, "x")
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        z.writestr("other.shp", shp.getvalue())
        z.writestr("other.shx", shx.getvalue())
        z.writestr("other.dbf", dbf.getvalue())
    return out.getvalue()


def test_mapping_converts_units_and_names_bad_values(client, rx):  # noqa: F811
    h, fid = rx["h"], rx["field"]["id"]
    data = _shp([100.0, 200.0], rx["field"]["geometry"])
    pre = _post(client, h, fid, data).json()
    assert pre["suggested_rate_column"] is None and list(pre["numeric_columns"]) == ["N_LBAC"]
    mapped = _post(client, h, fid, data, rate_column="N_LBAC", unit="lb/ac").json()
    assert mapped["mapping"]["min_rate_kg_ha"] == pytest.approx(112.085, abs=1e-3)
    assert mapped["mapping"]["max_rate_kg_ha"] == pytest.approx(224.170, abs=1e-3)
    bad = _post(client, h, fid, data, rate_column="NOTE")
    assert bad.status_code == 422 and "feature 0: NOTE='x'" in bad.json()["detail"]
    missing = _post(client, h, fid, data, rate_column="RATE")
    assert missing.status_code == 422 and "not in the file" in missing.json()["detail"]
    unit = _post(client, h, fid, data, rate_column="N_LBAC", unit="bushels")
    assert unit.status_code == 422
    ok = _post(client, h, fid, data, rate_column="N_LBAC", unit="lb/ac", confirm=pre["sha256"],
               default_rate_kg_ha=7)  # fmt: skip
    assert ok.status_code == 201, ok.text
    cells = all_cells(client, h, ok.json()["created"]["prescription_id"])
    rates = {round(c["properties"]["rate_kg_ha"], 2) for c in cells}
    assert rates <= {112.09, 224.17, 7.0} and {112.09, 224.17} <= rates


def test_volume_unit_takes_a_density_and_far_zones_are_refused(client, rx):  # noqa: F811
    from tests.support.plans import make_field, rectangle

    h, fid = rx["h"], rx["field"]["id"]
    exp = client.get(f"{API}/prescriptions/{rx['id']}/export?format=shapefile", headers=h)
    plain = _post(client, h, fid, exp.content, rate_column="RATE").json()["mapping"]
    assert plain["distance_m"] == 0 and plain["overlap_pct"] > 90 and plain["warning"] is None
    no_density = _post(client, h, fid, exp.content, rate_column="RATE", unit="l/ha")
    assert no_density.status_code == 422 and "density" in no_density.json()["detail"]
    vol = _post(client, h, fid, exp.content, rate_column="RATE", unit="l/ha", density_kg_l=1.25)
    assert vol.status_code == 200, vol.text
    assert vol.json()["mapping"]["max_rate_kg_ha"] == pytest.approx(
        plain["max_rate_kg_ha"] * 1.25, rel=1e-3
    )
    # the same zones offered to a field 1 degree further north (about 111 km)
    lon0, lat0 = rx["field"]["bbox"][0], rx["field"]["bbox"][1] + 1.0
    far = make_field(client, h, rectangle(lon0, lat0, 200, 200), name="Far away")
    pre = _post(client, h, far, exp.content, rate_column="RATE")
    m = pre.json()["mapping"]
    assert 100_000 < m["distance_m"] < 125_000 and "km from field 'Far away'" in m["warning"]
    n_rx = len(client.get(f"{API}/prescriptions", headers=h).json()["items"])
    ok = _post(client, h, far, exp.content, rate_column="RATE", confirm=pre.json()["sha256"])
    assert ok.status_code == 422 and "does not overlap" in ok.json()["detail"]
    assert len(client.get(f"{API}/prescriptions", headers=h).json()["items"]) == n_rx
