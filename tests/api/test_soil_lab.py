"""Soil-lab import assistant API on PostGIS: preview stores nothing, confirm stores all or
nothing, append vs replace, mapping and units sent by the user, rows outside the field."""

from __future__ import annotations

import json

import numpy as np
import pytest
from fieldrx.agronomy.soil_lab import P_PER_P2O5
from fieldrx.geo.crs import transform_xy

from tests.support.plans import API, make_field, rectangle

FIELD = rectangle(9.90, 51.55, 200, 150)  # near Göttingen: UTM zone 32
(LON0, LAT0), (LON1, LAT1) = FIELD["coordinates"][0][0], FIELD["coordinates"][0][2]


def _points(n: int = 3) -> list[tuple[float, float]]:
    return [
        (LON0 + (LON1 - LON0) * (i + 0.5) / n, LAT0 + (LAT1 - LAT0) * (j + 0.5) / n)
        for i in range(n)
        for j in range(n)
    ]


def german_csv(extra: str = "", epsg: int = 25832) -> bytes:
    """A lab file in ETRS89/UTM 32N (or another EPSG), ';' and decimal commas, cp1252."""
    pts = np.array(_points())
    x, y = transform_xy(pts[:, 0], pts[:, 1], 4326, epsg)
    lines = ["Probe;Rechtswert;Hochwert;Tiefe (cm);Nmin (kg/ha);P2O5 (mg/100g);Humus (%)"]
    for k, (xi, yi) in enumerate(zip(x, y, strict=True), start=1):
        lines.append(f"P{k};{xi:.2f};{yi:.2f};0-30;{40 + k};{12 + k},5;2,{k}".replace(".", ","))
    return ("\n".join(lines) + "\n" + extra).encode("cp1252")


def _post(client, h, fid, route, data, mapping=None, name="labor.csv", **params):
    form = {"mapping": json.dumps(mapping)} if mapping is not None else {}
    return client.post(
        f"{API}/fields/{fid}/soil-imports{route}",
        headers=h,
        params=params,
        data=form,
        files={"file": (name, data, "text/csv")},
    )


def _samples(client, h, fid) -> list[dict]:
    return client.get(f"{API}/fields/{fid}/soil-samples", headers=h).json()["features"]


def test_preview_recognises_german_file_and_stores_nothing(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h, FIELD)
    r = _post(client, h, fid, "/preview", german_csv())
    assert r.status_code == 200, r.text
    p = r.json()
    assert p["delimiter"] == ";" and p["decimal_comma"] is True
    assert p["mapping"]["columns"]["x"] == "Rechtswert" and p["mapping"]["epsg"] == 25832
    assert p["mapping"]["units"] == {"depth": "cm", "n": "kg/ha", "p": "P2O5 mg/100g", "om": "%"}
    assert (p["n_rows"], p["n_accepted"], p["n_inside"], p["n_rejected"], p["n_outside"]) == (
        9,
        9,
        9,
        0,
        0,
    )
    row = p["rows"][0]
    assert row["n_mg_kg"] == pytest.approx(41 * 10 / (30 * 1.5))
    assert row["p_mg_kg"] == pytest.approx(135 * P_PER_P2O5)
    assert row["om_g_kg"] == pytest.approx(21.0) and row["depth_cm"] == 30
    assert {o["epsg"] for o in p["crs_options"]} >= {4326, 25832, 31467, 4647}
    assert next(c for c in p["columns"] if c["name"] == "Nmin (kg/ha)")["target"] == "n"
    assert _samples(client, h, fid) == []
    assert client.get(f"{API}/fields/{fid}/soil-imports", headers=h).json()["total"] == 0


def test_user_mapping_units_and_crs_are_applied(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h, FIELD)
    data = german_csv(epsg=31467)  # Gauss-Krüger zone 3
    p = _post(client, h, fid, "/preview", data).json()
    assert p["mapping"]["epsg"] == 31467 and p["n_inside"] == 9
    m = p["mapping"]
    m["units"]["n"] = "mg/kg"  # the lab's Nmin column is mg/kg after all
    del m["columns"]["om"]  # humus not wanted
    m["epsg"] = 25832  # the wrong system: every row lands far away
    p = _post(client, h, fid, "/preview", data, m).json()
    assert p["n_outside"] == 9 and p["n_inside"] == 0
    m["epsg"] = 31467
    r = _post(client, h, fid, "", data, m)
    assert r.status_code == 201, r.text
    assert r.json()["imported"] == 9
    s = {f["properties"]["sample_id"]: f["properties"] for f in _samples(client, h, fid)}
    assert s["P1"]["n_mg_kg"] == 41 and s["P1"]["om_pct"] is None


def test_append_and_replace(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h, FIELD)
    assert _post(client, h, fid, "", german_csv()).status_code == 201
    lonlat = "sample_id,lon,lat,n_mg_kg\n" + "".join(
        f"L{i},{lo:.7f},{la:.7f},90\n" for i, (lo, la) in enumerate(_points(2))
    )
    r = _post(client, h, fid, "", lonlat.encode(), name="more.csv", mode="append")
    assert r.status_code == 201 and r.json()["replaced"] == 0
    assert len(_samples(client, h, fid)) == 13
    p = _post(client, h, fid, "/preview", german_csv("P10;x;y;;;;\n")).json()
    assert p["n_existing"] == 13
    r = _post(client, h, fid, "", lonlat.encode() + b"L9,9.9001,51.5501,70\n", mode="replace")
    assert r.status_code == 201, r.text
    assert r.json()["replaced"] == 13 and "13 earlier samples replaced" in r.json()["message"]
    assert len(_samples(client, h, fid)) == 5
    assert client.get(f"{API}/fields/{fid}/soil-imports", headers=h).json()["total"] == 1
    # the same file again after a replace of it: refused, the field keeps its samples
    r = _post(client, h, fid, "", lonlat.encode() + b"L9,9.9001,51.5501,70\n", mode="append")
    assert r.status_code == 409
    assert len(_samples(client, h, fid)) == 5


def test_rejected_rows_store_nothing_and_replace_deletes_nothing(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h, FIELD)
    assert _post(client, h, fid, "", german_csv()).status_code == 201
    bad = german_csv("P10;500000;5712000;0-30;n.b.;12,0;2,0\n")  # row 11
    p = _post(client, h, fid, "/preview", bad).json()
    assert p["n_rejected"] == 1
    assert p["rejected"][0]["row"] == 11 and p["rejected"][0]["column"] == "Nmin (kg/ha)"
    assert "n.b." in p["rejected"][0]["message"]
    r = _post(client, h, fid, "", bad, mode="replace")
    assert r.status_code == 422
    body = r.json()
    assert (
        body["imported"] == 0 and "row 11" in body["detail"] and "skip_rejected" in body["detail"]
    )
    assert len(_samples(client, h, fid)) == 9  # replace rolled back with the refusal
    r = _post(client, h, fid, "", bad, mode="replace", skip_rejected="true")
    assert r.status_code == 201 and r.json()["imported"] == 9 and r.json()["skipped"] == 1


def test_rows_outside_are_counted_listed_and_only_stored_when_asked(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h, FIELD)
    far = german_csv("P10;500000;5712000;0-30;44;12,0;2,0\n")  # ~40 km away
    p = _post(client, h, fid, "/preview", far).json()
    assert p["n_outside"] == 1 and p["n_inside"] == 9 and p["n_accepted"] == 10
    assert p["outside"][0]["row"] == 11 and p["outside"][0]["sample_id"] == "P10"
    assert p["outside"][0]["distance_m"] > 10_000
    r = _post(client, h, fid, "", far)
    assert r.status_code == 201
    assert r.json()["imported"] == 9 and r.json()["n_outside"] == 1
    assert r.json()["outside_stored"] is False


def test_replace_refused_when_no_row_lies_in_the_field_keeps_the_samples(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h, FIELD)
    assert _post(client, h, fid, "", german_csv()).status_code == 201
    r = _post(client, h, fid, "", german_csv(epsg=31467), mode="replace", mapping=None)
    assert r.status_code == 201  # guessed GK, inside: a real replace
    wrong = {
        "columns": {"x": "Rechtswert", "y": "Hochwert", "n": "Nmin (kg/ha)"},
        "units": {"n": "kg/ha"},
        "epsg": 25832,
    }
    r = _post(client, h, fid, "", german_csv(epsg=31467), wrong, mode="replace")
    assert r.status_code in (409, 422)
    assert len(_samples(client, h, fid)) == 9


def test_bad_mapping_and_bad_files_are_422_naming_the_problem(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h, FIELD)
    r = _post(client, h, fid, "/preview", german_csv(), {"columns": {"nitrogen": "Nmin"}})
    assert r.status_code == 422 and r.json()["where"] == "mapping"
    r = _post(client, h, fid, "/preview", german_csv(), {"columns": {}, "colour": 1})
    assert r.status_code == 422 and "colour" in r.json()["detail"]
    m = {"columns": {"x": "Rechtswert", "y": "Hochwert", "n": "Nmin (kg/ha)"}, "epsg": 999999}
    r = _post(client, h, fid, "/preview", german_csv(), m)
    assert r.status_code == 422 and "EPSG" in r.json()["detail"]
    p = _post(client, h, fid, "/preview", german_csv(), {"columns": {"n": "Nmin (kg/ha)"}}).json()
    assert p["mapping_ok"] is False and p["n_accepted"] == 0
    assert any("no column mapped to x" in e["message"] for e in p["rejected"])
    r = _post(client, h, fid, "", german_csv(), {"columns": {"n": "Nmin (kg/ha)"}})
    assert r.status_code == 422 and r.json()["imported"] == 0
    r = _post(client, h, fid, "/preview", b"PK\x03\x04", name="labor.xlsx")
    assert r.status_code == 422 and "CSV" in r.json()["detail"]
    v = org.headers("viewer")
    assert _post(client, v, fid, "/preview", german_csv()).status_code == 403
    assert _samples(client, h, fid) == []


def test_example_file_round_trips(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h, FIELD)
    r = client.get(f"{API}/fields/{fid}/soil-imports/example.csv", headers=org.headers("viewer"))
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
    assert r.headers["x-coordinate-system"] == "EPSG:25832"
    assert r.text.startswith("Probe;Rechtswert;Hochwert;Tiefe (cm);Nmin (kg/ha);P2O5 (mg/100g)")
    up = _post(client, h, fid, "", r.content, name="example.csv")
    assert up.status_code == 201, up.text
    assert up.json()["imported"] == 9 and up.json()["n_outside"] == 0


def test_n_form_is_part_of_the_mapping_and_the_model_reads_only_alkali_n(client, org) -> None:
    """Nmin went into n_mg_kg and fed seed 001's model as if it were alkali-hydrolysable N;
    the mapping now says which N a column holds and the model refuses another form."""
    h = org.headers()
    fid = make_field(client, h, FIELD)
    p = _post(client, h, fid, "/preview", german_csv()).json()
    assert p["mapping"]["n_form"] == "mineral"  # "Nmin (kg/ha)"
    r = _post(client, h, fid, "", german_csv())
    assert r.status_code == 201, r.text
    plan = client.post(
        f"{API}/fields/{fid}/plans", headers=h, json={"swath_width_m": 12, "cell_length_m": 10}
    ).json()
    r = client.post(
        f"{API}/plans/{plan['id']}/prescriptions",
        headers=h,
        json={"model": "nutrient_balance", "params": {"target_yield_kg_ha": 8000},
              "crop": "winter_wheat", "product_key": "default:can"},
    )  # fmt: skip
    assert r.status_code == 422, r.text
    assert "alkali-hydrolysable" in r.json()["detail"] and "mineral" in r.json()["detail"]

    # the seed's own column name is recognised as alkali-hydrolysable N
    pts = _points()
    seed = "sample_id,lon,lat,alkali_n_mg_kg\n" + "".join(
        f"S{k},{lon:.7f},{lat:.7f},{90 + k}\n" for k, (lon, lat) in enumerate(pts)
    )
    fid2 = make_field(client, h, FIELD)
    p = _post(client, h, fid2, "/preview", seed.encode()).json()
    assert p["mapping"]["columns"]["n"] == "alkali_n_mg_kg", p["mapping"]
    assert p["mapping"]["n_form"] == "alkali_hydrolysable"
    # a user who says the column is total N is believed and the model refuses it
    m = {**p["mapping"], "n_form": "total"}
    r = _post(client, h, fid2, "", seed.encode(), mapping=m)
    assert r.status_code == 201, r.text
    plan2 = client.post(
        f"{API}/fields/{fid2}/plans", headers=h, json={"swath_width_m": 12, "cell_length_m": 10}
    ).json()
    r = client.post(
        f"{API}/plans/{plan2['id']}/prescriptions",
        headers=h,
        json={"model": "nutrient_balance", "params": {"target_yield_kg_ha": 8000},
              "crop": "winter_wheat", "product_key": "default:can"},
    )  # fmt: skip
    assert r.status_code == 422 and "total N" in r.json()["detail"], r.text
