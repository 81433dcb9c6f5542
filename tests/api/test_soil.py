"""Soil-sample import API: CSV / GeoJSON, x/y + EPSG, per-row errors, all-or-nothing, outside."""

from __future__ import annotations

import json

from tests.support.plans import API, make_field

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


def _far_csv(n: int = 17, dlon: float = 1.0) -> str:
    """n samples about dlon degrees (~94 km per degree here) east of SMALL_PLOT."""
    rows = [f"F{i},{112.32005 + dlon + i * 1e-4:.6f},32.13005,20,{80 + i}" for i in range(n)]
    return "sample_id,lon,lat,depth_cm,n_mg_kg\n" + "\n".join(rows) + "\n"


def _n_samples(client, h, fid) -> int:
    return len(client.get(f"{API}/fields/{fid}/soil-samples", headers=h).json()["features"])


def test_samples_from_another_field_are_refused_and_not_stored(client, org) -> None:
    """A CSV from a field ~100 km away was accepted ("17 samples")."""
    h = org.headers()
    fid = make_field(client, h)
    r = _post(client, h, fid, "far.csv", _far_csv())
    assert r.status_code == 422, r.text
    body = r.json()
    assert body["imported"] == 0 and len(body["outside"]) == 17
    assert "none of the 17 samples" in body["detail"] and "m outside" in body["detail"]
    assert all(o["distance_m"] > 90_000 for o in body["outside"])
    assert _n_samples(client, h, fid) == 0
    assert client.get(f"{API}/fields/{fid}/soil-imports", headers=h).json()["total"] == 0


def test_outside_rows_are_listed_and_stored_only_when_asked(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h)
    data = GOOD_CSV + "FAR,112.40,32.20,20,80\n"
    r = _post(client, h, fid, "soil.csv", data)
    assert r.status_code == 201, r.text
    body = r.json()
    (far,) = body["outside"]
    assert (far["row"], far["sample_id"]) == (5, "FAR") and far["distance_m"] > 9000
    assert body["imported"] == 3 and body["n_outside"] == 1 and body["outside_stored"] is False
    assert "1 outside the field" in body["message"] and "not stored" in body["message"]
    assert {
        f["properties"]["sample_id"]
        for f in client.get(f"{API}/fields/{fid}/soil-samples", headers=h).json()["features"]
    } == {"S1", "S2", "S3"}
    # asked to: another file with an outside row, stored as asked
    data2 = "sample_id,lon,lat,n_mg_kg\nS9,112.32010,32.13010,90\nFAR2,112.40,32.20,80\n"
    r = _post(client, h, fid, "soil2.csv", data2, include_outside="true")
    assert r.status_code == 201, r.text
    assert r.json()["imported"] == 2 and r.json()["outside_stored"] is True
    assert _n_samples(client, h, fid) == 5


def test_identical_reupload_is_recognised(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h)
    first = _post(client, h, fid, "soil.csv", GOOD_CSV)
    assert first.status_code == 201
    again = _post(client, h, fid, "soil-copy.csv", GOOD_CSV)
    assert again.status_code == 409, again.text
    body = again.json()
    assert body["imported"] == 0 and body["duplicate_of"]["id"] == first.json()["import"]["id"]
    assert "already imported" in body["detail"]
    assert _n_samples(client, h, fid) == 3  # not doubled
    # the same file on another field is a different import
    other = make_field(client, h, name="other")
    assert _post(client, h, other, "soil.csv", GOOD_CSV).status_code == 201


def test_imports_are_listed_and_deleted(client, make_org) -> None:
    a, b = make_org(), make_org()
    h = a.headers()
    fid = make_field(client, h)
    i1 = _post(client, h, fid, "one.csv", GOOD_CSV).json()["import"]
    two = "sample_id,lon,lat,n_mg_kg\nT1,112.32010,32.13010,90\nT2,112.32020,32.13012,91\n"
    i2 = _post(client, h, fid, "two.csv", two).json()["import"]
    lst = client.get(f"{API}/fields/{fid}/soil-imports", headers=a.headers("viewer")).json()
    assert [(i["id"], i["filename"], i["n_stored"]) for i in lst["items"]] == [
        (i2["id"], "two.csv", 2),
        (i1["id"], "one.csv", 3),
    ]
    assert lst["items"][0]["sha256"].startswith("sha256:")
    url = f"{API}/fields/{fid}/soil-imports/{i1['id']}"
    assert client.delete(url, headers=a.headers("viewer")).status_code == 403
    assert client.delete(url, headers=b.headers()).status_code == 404
    r = client.delete(url, headers=h)
    assert r.status_code == 200 and r.json() == {"deleted": 3}
    assert client.delete(url, headers=h).status_code == 404
    feats = client.get(f"{API}/fields/{fid}/soil-samples", headers=h).json()["features"]
    assert {f["properties"]["sample_id"] for f in feats} == {"T1", "T2"}
    assert all(f["properties"]["import_id"] == i2["id"] for f in feats)
    # one sample
    one = feats[0]["properties"]["id"]
    assert client.delete(f"{API}/fields/{fid}/soil-samples/{one}", headers=h).status_code == 200
    assert client.delete(f"{API}/fields/{fid}/soil-samples/{one}", headers=h).status_code == 404
    lst = client.get(f"{API}/fields/{fid}/soil-imports", headers=h).json()
    assert [(i["id"], i["n_stored"]) for i in lst["items"]] == [(i2["id"], 1)]
    # once deleted, the file can be imported again
    assert _post(client, h, fid, "one.csv", GOOD_CSV).status_code == 201
    # deleting everything removes the imports too
    assert client.delete(f"{API}/fields/{fid}/soil-samples", headers=h).json() == {"deleted": 4}
    assert client.get(f"{API}/fields/{fid}/soil-imports", headers=h).json()["total"] == 0


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
