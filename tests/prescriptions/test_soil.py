"""Soil-sample import API: CSV / GeoJSON, x/y + EPSG, per-row errors, all-or-nothing, outside."""

from __future__ import annotations

import json

from tests.plans.helpers import API, make_field

# inside SMALL_PLOT (112.32000..112.32037, 32.13000..32.13021)
GOOD_CSV = (
    "sample_id,lon,lat,depth_cm,n_mg_kg,p_mg_kg,k_mg_kg,om_g_kg,ph,ndvi\n"
    "S1,112.32005,32.13005,20,95,12,110,18,6.5,0.3\n"
    "S2,112.32030,32.13005,20,105,,,,,0.5\n"
    "S3,112.32018,32.13015,20,100,,,,,\n"
)


def _post(client, headers, fid, name, data, **params):
    return client.post(
        f"{API}/fields/{fid}/soil-samples",
        headers=headers,
        params=params,
        files={"file": (name, data, "text/csv")},
    )


def test_csv_import_list_delete(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h)
    r = _post(client, h, fid, "soil.csv", GOOD_CSV)
    assert r.status_code == 201, r.text
    body = r.json()
    assert body["imported"] == 3 and body["errors"] == [] and body["n_outside"] == 0
    fc = client.get(f"{API}/fields/{fid}/soil-samples", headers=org.headers("viewer")).json()
    assert fc["type"] == "FeatureCollection" and len(fc["features"]) == 3
    s1 = next(f for f in fc["features"] if f["properties"]["sample_id"] == "S1")
    assert s1["geometry"]["coordinates"] == [112.32005, 32.13005]
    assert s1["properties"]["n_mg_kg"] == 95 and s1["properties"]["om_pct"] == 1.8
    assert s1["properties"]["ndvi"] == 0.3
    assert (
        client.delete(f"{API}/fields/{fid}/soil-samples", headers=org.headers("viewer")).status_code
        == 403
    )
    d = client.delete(f"{API}/fields/{fid}/soil-samples", headers=h)
    assert d.status_code == 200 and d.json() == {"deleted": 3}
    assert client.get(f"{API}/fields/{fid}/soil-samples", headers=h).json()["features"] == []


def test_bad_rows_reject_everything_with_row_and_column(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h)
    bad = GOOD_CSV + "S4,112.32010,abc,20,100\nS5,112.32010,32.13010,20,\n"
    r = _post(client, h, fid, "soil.csv", bad)
    assert r.status_code == 422
    body = r.json()
    assert body["imported"] == 0
    errs = {(e["row"], e["column"]) for e in body["errors"]}
    assert (5, "lat") in errs and (6, "n_mg_kg") in errs
    assert "row 5" in body["detail"] and "'lat'" in body["detail"]
    assert client.get(f"{API}/fields/{fid}/soil-samples", headers=h).json()["features"] == []

    r = _post(client, h, fid, "soil.csv", bad, skip_bad_rows="true")
    assert r.status_code == 201
    assert r.json()["imported"] == 3 and r.json()["skipped"] == 2
    assert len(client.get(f"{API}/fields/{fid}/soil-samples", headers=h).json()["features"]) == 3


def test_missing_column_and_unreadable_file(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h)
    r = _post(client, h, fid, "soil.csv", "sample_id,lon,lat\nA,112.32,32.13\n")
    assert r.status_code == 422
    assert r.json()["errors"][0]["column"] == "n_mg_kg"
    r = _post(client, h, fid, "soil.xlsx", b"PK\x03\x04")
    assert r.status_code == 422 and "unsupported" in r.json()["detail"]
    r = _post(client, h, fid, "soil.csv", "x,y,n\n1,2,3\n", epsg=999999)
    assert r.status_code == 422 and "EPSG" in r.json()["detail"]


def test_outside_samples_are_reported(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h)
    data = GOOD_CSV + "FAR,112.40,32.20,20,80\n"
    r = _post(client, h, fid, "soil.csv", data)
    assert r.status_code == 201
    assert r.json()["outside"] == [{"row": 5, "sample_id": "FAR"}]


def test_xy_with_epsg_and_geojson(client, org) -> None:
    from fieldrx.geo.crs import lonlat_to_utm_xy

    h = org.headers()
    fid = make_field(client, h)
    x, y = lonlat_to_utm_xy([112.32010], [32.13010], 32649)
    csv = f"id,x,y,n\nP1,{x[0]:.3f},{y[0]:.3f},88\n"
    r = _post(client, h, fid, "utm.csv", csv, epsg=32649)
    assert r.status_code == 201, r.text
    feats = client.get(f"{API}/fields/{fid}/soil-samples", headers=h).json()["features"]
    lon, lat = feats[0]["geometry"]["coordinates"]
    assert abs(lon - 112.32010) < 1e-7 and abs(lat - 32.13010) < 1e-7

    gj = {
        "type": "FeatureCollection",
        "features": [
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [112.32020, 32.13010]},
                "properties": {"sample_id": "G1", "n_mg_kg": 77, "ndvi": 0.4},
            },
            {"type": "Feature", "geometry": {"type": "LineString", "coordinates": []}},
        ],
    }
    r = _post(client, h, fid, "s.geojson", json.dumps(gj))
    assert r.status_code == 422
    assert r.json()["errors"][0] == {
        "row": 1,
        "column": "geometry",
        "message": "expected a Point geometry",
        "kind": "feature",
    }
    gj["features"].pop()
    r = _post(client, h, fid, "s.geojson", json.dumps(gj))
    assert r.status_code == 201
    feats = client.get(f"{API}/fields/{fid}/soil-samples", headers=h).json()["features"]
    assert {f["properties"]["sample_id"] for f in feats} == {"P1", "G1"}
    assert (
        next(f for f in feats if f["properties"]["sample_id"] == "G1")["properties"]["ndvi"] == 0.4
    )


def test_soil_tenancy_and_roles(client, make_org) -> None:
    a, b = make_org(), make_org()
    fid = make_field(client, a.headers())
    assert _post(client, a.headers(), fid, "soil.csv", GOOD_CSV).status_code == 201
    assert _post(client, b.headers(), fid, "soil.csv", GOOD_CSV).status_code == 404
    assert client.get(f"{API}/fields/{fid}/soil-samples", headers=b.headers()).status_code == 404
    assert client.delete(f"{API}/fields/{fid}/soil-samples", headers=b.headers()).status_code == 404
    assert _post(client, a.headers("viewer"), fid, "soil.csv", GOOD_CSV).status_code == 403
    n = len(client.get(f"{API}/fields/{fid}/soil-samples", headers=a.headers()).json()["features"])
    assert n == 3
