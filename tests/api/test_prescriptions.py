"""Prescriptions API on PostGIS: models, interpolation, meter flags, versions, edits, 422s."""

from __future__ import annotations

import pytest
from sqlalchemy import text

from tests.support import machine_body
from tests.support.plans import API
from tests.support.prescriptions import FIELD, all_cells, make_rx, samples_csv, setup_plan

# machine defaults: seed 001 calibration, width 2.3 m, 0.8..2.5 m/s -> about 607.9..882.1 kg/ha
LO, HI = 6711.6 / (6 * 2.3 * 0.8), 30431.6 / (6 * 2.3 * 2.5)


def _machine(client, headers) -> int:
    r = client.post(f"{API}/machines", headers=headers, json=machine_body())
    assert r.status_code == 201, r.text
    return r.json()["id"]


def test_worked_example_nutrient_balance(client, org) -> None:
    """docs/science.md: M 2500, n 100, x 0.25 -> about 700.4 kg/ha in every cell."""
    h = org.headers()
    plan = setup_plan(client, h, samples_csv([100.0]))
    rx = make_rx(
        client,
        h,
        plan["id"],
        name="Rape N",
        model="nutrient_balance",
        params={"target_yield_kg_ha": 2500, "n_fraction": 0.25},
        interpolation="idw",
    )
    assert rx["current_version"] == 1 and rx["model"] == "nutrient_balance"
    s = rx["summary"]
    assert s["n_cells"] == plan["n_cells"]
    assert s["rate_mean_kg_ha"] == pytest.approx(700.4, abs=0.1)
    assert s["rate_min_kg_ha"] == pytest.approx(s["rate_max_kg_ha"])
    assert s["product_kg"] == pytest.approx(700.4 * s["area_m2"] / 1e4, rel=1e-3)
    assert s["area_m2"] == pytest.approx(60 * 40, rel=0.01)
    assert sum(s["histogram"]["counts"]) == plan["n_cells"]
    cells = all_cells(client, h, rx["id"])
    assert len(cells) == plan["n_cells"]
    assert all(c["properties"]["rate_kg_ha"] == pytest.approx(700.4, abs=0.1) for c in cells)
    assert all(c["properties"]["source_value"] == pytest.approx(100.0) for c in cells)
    # aliases the UI uses give the same rates
    rx2 = make_rx(
        client,
        h,
        plan["id"],
        model="nutrient_balance",
        params={
            "target_yield_kg_ha": 2500,
            "nutrient_fraction": 0.25,
            "uptake_kg_per_100kg": 5.8,
            "utilisation": 0.342,
            "nutrient": "n_mg_kg",
        },
        interpolation="idw",
    )
    assert rx2["summary"]["rate_mean_kg_ha"] == pytest.approx(700.4, abs=0.1)
    listed = client.get(f"{API}/prescriptions?plan_id={plan['id']}", headers=h).json()
    assert [r["id"] for r in listed["items"]] == [rx["id"], rx2["id"]]
    by_plan = client.get(f"{API}/plans/{plan['id']}/prescriptions", headers=h).json()
    assert by_plan["total"] == 2


def test_model_rates_outside_meter_range_are_kept_and_flagged(client, org) -> None:
    """A 300 kg/ha model output was stored as the meter's floor (~608)."""
    h = org.headers()
    plan = setup_plan(client, h)
    mid = _machine(client, h)
    low = make_rx(
        client, h, plan["id"], model="uniform", params={"rate_kg_ha": 300}, machine_id=mid
    )
    s = low["summary"]
    assert s["meter_range_kg_ha"] == pytest.approx([LO, HI], rel=1e-4)
    assert s["meter"]["speed_min_kmh"] == pytest.approx(0.8 * 3.6)
    assert s["meter"]["rate_min_kg_ha"] == pytest.approx(LO, rel=1e-4)
    assert s["rate_min_kg_ha"] == 300 and s["rate_max_kg_ha"] == 300  # stored as asked
    assert s["flagged"]["below_meter_range"] == plan["n_cells"]
    assert s["attention"]["count"] == plan["n_cells"]
    assert s["attention"]["area_m2"] == pytest.approx(s["area_m2"], rel=1e-6)
    assert s["attention"]["seq"][:3] == [0, 1, 2]
    assert s["flagged_area_m2"]["below_meter_range"] == pytest.approx(s["area_m2"], rel=1e-6)
    assert low["stats"]["out_of_meter_range_count"] == plan["n_cells"]
    assert low["stats"]["attention_area_m2"] == pytest.approx(s["area_m2"], rel=1e-6)
    c = all_cells(client, h, low["id"])[0]["properties"]
    assert c["flags"] == ["below_meter_range"] and c["out_of_meter_range"] is True
    assert c["rate_kg_ha"] == 300
    high = make_rx(client, h, plan["id"], model="constant", params={"rate": 2000}, machine_id=mid)
    assert high["summary"]["rate_max_kg_ha"] == 2000
    assert high["summary"]["flagged"]["above_meter_range"] == plan["n_cells"]
    # explicit speed range without a machine needs an explicit calibration (no hidden default)
    r = client.post(
        f"{API}/plans/{plan['id']}/prescriptions",
        headers=h,
        json={"model": "uniform", "params": {"rate_kg_ha": 750}, "speed_min_kmh": 9},
    )
    assert r.status_code == 422 and "calibration" in r.json()["detail"]
    ok = make_rx(
        client,
        h,
        plan["id"],
        model="uniform",
        params={"rate_kg_ha": 750},
        speed_min_kmh=9,
        speed_max_kmh=9,
        calibration=machine_body()["calibration"],
    )
    assert ok["summary"]["flagged"]["above_meter_range"] == 0
    assert ok["summary"]["rate_mean_kg_ha"] == pytest.approx(750)
    # a rate of 0 means "meter off" and is never flagged
    off = make_rx(client, h, plan["id"], model="uniform", params={"rate_kg_ha": 0}, machine_id=mid)
    assert off["summary"]["rate_max_kg_ha"] == 0 and off["stats"]["attention_count"] == 0


def test_cell_mean_no_data_gets_fallback_and_flag(client, org) -> None:
    h = org.headers()
    plan = setup_plan(client, h, samples_csv([80.0], grid=2))
    rx = make_rx(
        client,
        h,
        plan["id"],
        model="nutrient_balance",
        params={"target_yield_kg_ha": 2500, "n_fraction": 0.25},
        interpolation="cell_mean",
        fallback_rate_kg_ha=500,
    )
    cells = all_cells(client, h, rx["id"])
    nodata = [c for c in cells if "no_data" in c["properties"]["flags"]]
    have = [c for c in cells if "no_data" not in c["properties"]["flags"]]
    assert 1 <= len(have) <= 8 and len(nodata) == len(cells) - len(have)
    assert all(c["properties"]["rate_kg_ha"] == 500 for c in nodata)
    assert all(c["properties"]["source_value"] is None for c in nodata)
    assert all(c["properties"]["source_value"] == pytest.approx(80.0) for c in have)
    assert rx["stats"]["no_data_count"] == len(nodata)
    assert (
        rx["summary"]["flagged_seq"][: len(nodata)]
        == [c["properties"]["seq"] for c in nodata][:1000]
    )


def test_kriging_reports_cv_rmse_and_ndvi_model(client, org) -> None:
    h = org.headers()
    plan = setup_plan(client, h, samples_csv(grid=5), swath_width_m=6, cell_length_m=6)
    rx = make_rx(
        client,
        h,
        plan["id"],
        model="nutrient_balance",
        params={"target_yield_kg_ha": 2500, "n_fraction": 0.25},
        interpolation="kriging",
        interpolation_params={"variogram_model": "linear"},
    )
    interp = rx["summary"]["interpolation"]
    assert interp["method"] == "kriging" and interp["n_samples"] == 25
    assert interp["loo_rmse"] > 0 and rx["stats"]["kriging_cv_rmse"] == interp["loo_rmse"]
    rates = [c["properties"]["rate_kg_ha"] for c in all_cells(client, h, rx["id"])]
    assert max(rates) > min(rates)  # N gradient -> variable rates
    nd = make_rx(client, h, plan["id"], model="ndvi", params={}, interpolation="idw")
    s = nd["summary"]
    assert 180 - 1e-9 <= s["rate_min_kg_ha"] < s["rate_max_kg_ha"] <= 375 + 1e-9


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        (
            {
                "model": "nutrient_balance",
                "params": {"target_yield_kg_ha": 2500, "n_fraction": 0.25},
            },
            "needs soil samples",
        ),
        ({"model": "uniform", "params": {}}, "rate_kg_ha"),
        ({"model": "uniform", "params": {"rate_kg_ha": 100, "bogus": 1}}, "unknown parameters"),
        ({"model": "magic", "params": {}}, "unknown model"),
        ({"model": "uniform", "params": {"rate_kg_ha": 100}, "machine_id": 999999}, "machine"),
        (
            {
                "model": "uniform",
                "params": {"rate_kg_ha": 100},
                "speed_min_kmh": 20,
                "speed_max_kmh": 5,
            },
            "speed range",
        ),
    ],
)
def test_bad_requests_are_422_and_store_nothing(client, org, db, body, needle) -> None:
    h = org.headers()
    plan = setup_plan(client, h)
    r = client.post(f"{API}/plans/{plan['id']}/prescriptions", headers=h, json=body)
    assert r.status_code == 422, r.text
    assert needle in r.json()["detail"]
    n = db.scalar(text("SELECT count(*) FROM prescriptions WHERE plan_id=:p"), {"p": plan["id"]})
    assert n == 0


def test_bad_model_parameter_value(client, org) -> None:
    h = org.headers()
    plan = setup_plan(client, h, samples_csv([100.0]))
    r = client.post(
        f"{API}/plans/{plan['id']}/prescriptions",
        headers=h,
        json={"model": "nutrient_balance", "params": {"target_yield_kg_ha": 2500, "n_fraction": 2}},
    )
    assert r.status_code == 422 and "n_fraction" in r.json()["detail"]


def test_edits_make_new_versions_and_leave_old_ones(client, org) -> None:
    h = org.headers()
    plan = setup_plan(client, h)
    mid = _machine(client, h)
    rx = make_rx(client, h, plan["id"], model="uniform", params={"rate_kg_ha": 700}, machine_id=mid)
    v1 = all_cells(client, h, rx["id"], 1)
    r = client.post(
        f"{API}/prescriptions/{rx['id']}/edits",
        headers=h,
        json={
            "cells": [{"seq": 0, "rate_kg_ha": 800}, {"seq": 3, "rate_kg_ha": 850}],
            "note": "wet corner",
        },
    )
    assert r.status_code == 201, r.text
    body = r.json()
    assert body["current_version"] == 2 and body["new_version"] == 2 and body["edited_cells"] == 2
    assert [v["version"] for v in body["versions"]] == [1, 2]
    v2 = all_cells(client, h, rx["id"])
    assert v2[0]["properties"]["rate_kg_ha"] == 800 and v2[0]["properties"]["flags"] == ["manual"]
    p3 = v2[3]["properties"]
    assert p3["rate_kg_ha"] == 850 and p3["flags"] == ["manual"]
    assert [c["properties"] for c in v2[4:]] == [c["properties"] for c in v1[4:]]
    # version 1 unchanged
    assert all_cells(client, h, rx["id"], 1) == v1
    ver1 = client.get(f"{API}/prescriptions/{rx['id']}/versions/1", headers=h).json()
    assert ver1["summary"]["rate_max_kg_ha"] == 700 and ver1["version"] == 1
    ver2 = client.get(f"{API}/prescriptions/{rx['id']}/versions/2", headers=h).json()
    assert ver2["note"] == "wet corner" and ver2["summary"]["flagged"]["manual"] == 2
    vs = client.get(f"{API}/prescriptions/{rx['id']}/versions", headers=h).json()
    assert vs["current_version"] == 2 and [v["version"] for v in vs["items"]] == [1, 2]
    assert client.get(f"{API}/prescriptions/{rx['id']}/versions/3", headers=h).status_code == 404
    # zone painting: west half of the field
    (lon0, lat0), (lon1, lat1) = FIELD["coordinates"][0][0], FIELD["coordinates"][0][2]
    mid_lon = (lon0 + lon1) / 2
    zone = {
        "type": "Polygon",
        "coordinates": [
            [
                [lon0 - 1e-4, lat0 - 1e-4],
                [mid_lon, lat0 - 1e-4],
                [mid_lon, lat1 + 1e-4],
                [lon0 - 1e-4, lat1 + 1e-4],
                [lon0 - 1e-4, lat0 - 1e-4],
            ]
        ],
    }
    r = client.post(
        f"{API}/prescriptions/{rx['id']}/edits",
        headers=h,
        json={"zone": zone, "rate_kg_ha": 650, "note": "west"},
    )
    assert r.status_code == 201, r.text
    assert r.json()["current_version"] == 3
    painted = r.json()["edited_cells"]
    assert plan["n_cells"] * 0.3 < painted < plan["n_cells"] * 0.7
    v3 = all_cells(client, h, rx["id"], 3)
    zoned = [c for c in v3 if "zone" in c["properties"]["flags"]]
    assert len(zoned) == painted and all(c["properties"]["rate_kg_ha"] == 650 for c in zoned)
    assert all_cells(client, h, rx["id"], 2) == v2
    # bad edits
    for bad in (
        {"cells": [{"seq": 10**6, "rate_kg_ha": 1}]},
        {
            "zone": {
                "type": "Polygon",
                "coordinates": [[[0, 0], [0.001, 0], [0.001, 0.001], [0, 0]]],
            },
            "rate_kg_ha": 5,
        },
    ):
        r = client.post(f"{API}/prescriptions/{rx['id']}/edits", headers=h, json=bad)
        assert r.status_code == 422, r.text
    r = client.post(f"{API}/prescriptions/{rx['id']}/edits", headers=h, json={"note": "nothing"})
    assert r.status_code == 422
    assert client.get(f"{API}/prescriptions/{rx['id']}", headers=h).json()["current_version"] == 3


def test_delete_prescription(client, org, db) -> None:
    h = org.headers()
    plan = setup_plan(client, h)
    rx = make_rx(client, h, plan["id"], model="uniform", params={"rate_kg_ha": 100})
    assert (
        client.delete(f"{API}/prescriptions/{rx['id']}", headers=org.headers("viewer")).status_code
        == 403
    )
    assert client.delete(f"{API}/prescriptions/{rx['id']}", headers=h).status_code == 204
    assert client.get(f"{API}/prescriptions/{rx['id']}", headers=h).status_code == 404
    n = db.scalar(
        text(
            "SELECT count(*) FROM prescription_rates r JOIN prescription_versions v "
            "ON v.id = r.version_id "
            "WHERE v.prescription_id = :x"
        ),
        {"x": rx["id"]},
    )
    assert n == 0
    # deleting the plan deletes its prescriptions
    rx = make_rx(client, h, plan["id"], model="uniform", params={"rate_kg_ha": 100})
    assert client.delete(f"{API}/plans/{plan['id']}", headers=h).status_code == 204
    assert client.get(f"{API}/prescriptions/{rx['id']}", headers=h).status_code == 404


@pytest.mark.parametrize(
    ("edit", "needle"),
    [
        ({"cells": [{"seq": 2, "rate_kg_ha": 150}]}, "cell 2: 150 kg/ha is below"),
        ({"cells": [{"seq": 2, "rate_kg_ha": 5000}]}, "cell 2: 5000 kg/ha is above"),
        ({"zone": "FIELD", "rate_kg_ha": 120}, "zone rate: 120 kg/ha is below"),
    ],
)
def test_unmeterable_edits_are_refused_naming_limit_and_speed(
    client, org, db, edit, needle
) -> None:
    """An edit to 150 kg/ha or a 120 kg/ha zone was stored as 583.6."""
    h = org.headers()
    plan = setup_plan(client, h)
    mid = _machine(client, h)
    rx = make_rx(client, h, plan["id"], model="uniform", params={"rate_kg_ha": 700}, machine_id=mid)
    if edit.get("zone") == "FIELD":
        edit = {**edit, "zone": FIELD}
    r = client.post(f"{API}/prescriptions/{rx['id']}/edits", headers=h, json=edit)
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert needle in detail
    if "below" in needle:  # the floor and the slowest speed it assumes
        assert f"{LO:.1f} kg/ha" in detail and "2.88 km/h" in detail and "30 r/min" in detail
    else:
        assert f"{HI:.1f} kg/ha" in detail and "9 km/h" in detail and "130 r/min" in detail
    assert client.get(f"{API}/prescriptions/{rx['id']}", headers=h).json()["current_version"] == 1
    n = db.scalar(
        text("SELECT count(*) FROM prescription_versions WHERE prescription_id = :x"),
        {"x": rx["id"]},
    )
    assert n == 1
    # 0 (meter off) is always accepted
    r = client.post(
        f"{API}/prescriptions/{rx['id']}/edits",
        headers=h,
        json={"cells": [{"seq": 2, "rate_kg_ha": 0}]},
    )
    assert r.status_code == 201, r.text


def test_job_with_flagged_cells_needs_explicit_confirmation(client, org, db) -> None:
    """A prescription the machine cannot meter was sent without a word."""
    h = org.headers()
    plan = setup_plan(client, h)
    mid = _machine(client, h)
    low = make_rx(
        client, h, plan["id"], model="uniform", params={"rate_kg_ha": 300}, machine_id=mid
    )
    body = {"prescription_id": low["id"], "machine_id": mid}
    r = client.post(f"{API}/jobs", headers=h, json=body)
    assert r.status_code == 409, r.text
    err = r.json()
    n = plan["n_cells"]
    assert err["where"] == "confirm_flagged" and err["flagged"]["count"] == n
    assert err["flagged"]["area_m2"] == pytest.approx(low["summary"]["area_m2"], rel=1e-6)
    assert err["flagged"]["seq"][:2] == [0, 1]
    assert f"{n} cell(s)" in err["detail"] and "confirm these cells" in err["detail"]
    assert (
        db.scalar(text("SELECT count(*) FROM jobs WHERE prescription_id = :x"), {"x": low["id"]})
        == 0
    )
    r = client.post(f"{API}/jobs", headers=h, json={**body, "confirm_flagged": True})
    assert r.status_code == 201, r.text
    job = r.json()
    assert job["flagged_cells"] == n and job["flagged_confirmed"] is True
    assert f"{n} flagged cell(s) confirmed" in job["events"][0]["note"]
    # built without a machine (no meter check), sent to one that cannot meter it: still asked
    bare = make_rx(client, h, plan["id"], model="uniform", params={"rate_kg_ha": 300})
    assert bare["summary"]["attention"]["count"] == 0
    r = client.post(
        f"{API}/jobs", headers=h, json={"prescription_id": bare["id"], "machine_id": mid}
    )
    assert r.status_code == 409 and r.json()["flagged"]["out_of_meter_range"] == n
    # nothing flagged: no confirmation needed, and the job says so
    ok = make_rx(client, h, plan["id"], model="uniform", params={"rate_kg_ha": 700}, machine_id=mid)
    r = client.post(f"{API}/jobs", headers=h, json={"prescription_id": ok["id"], "machine_id": mid})
    assert r.status_code == 201, r.text
    assert r.json()["flagged_cells"] == 0 and r.json()["flagged_confirmed"] is False


def test_cells_without_a_nearby_sample_are_no_data_with_the_fallback_named(client, org) -> None:
    """IDW spread samples over the whole field (no_data 0)."""
    from tests.support.plans import make_field, make_plan, rectangle

    h = org.headers()
    long_field = rectangle(112.3501, 32.1501, 300, 40)  # 300 m x 40 m
    fid = make_field(client, h, long_field)
    (lon0, lat0) = long_field["coordinates"][0][0]
    rows = ["sample_id,lon,lat,n_mg_kg"]
    for i in range(4):  # four samples within the west 30 m
        rows.append(f"W{i},{lon0 + (5 + 8 * i) / 94_300:.7f},{lat0 + 20 / 110_574:.7f},{90 + i}")
    r = client.post(
        f"{API}/fields/{fid}/soil-samples",
        headers=h,
        files={"file": ("w.csv", "\n".join(rows) + "\n", "text/csv")},
    )
    assert r.status_code == 201, r.text
    plan = make_plan(client, h, fid)
    nb = {"target_yield_kg_ha": 2500, "n_fraction": 0.25}
    rx = make_rx(
        client, h, plan["id"], model="nutrient_balance", params=nb, interpolation="idw",
        fallback_rate_kg_ha=650,
    )  # fmt: skip
    s = rx["summary"]
    assert s["interpolation"]["search_distance_m"] == 50.0
    assert s["interpolation"]["search_distance_default"] is True
    nd = s["flagged"]["no_data"]
    assert 0.5 * plan["n_cells"] < nd < plan["n_cells"]  # the east of the field has no sample
    assert s["attention"]["count"] == nd and s["attention"]["area_m2"] > 0
    assert rx["fallback_rate_kg_ha"] == 650 and rx["stats"]["no_data_count"] == nd
    cells = all_cells(client, h, rx["id"])
    far = [c["properties"] for c in cells if c["properties"]["fallback"]]
    assert len(far) == nd and all(p["rate_kg_ha"] == 650 and p["flags"] == ["no_data"] for p in far)
    # an explicit unlimited radius is the caller's choice
    wide = make_rx(
        client, h, plan["id"], model="nutrient_balance", params=nb, interpolation="idw",
        interpolation_params={"radius_m": None},
    )  # fmt: skip
    assert wide["summary"]["flagged"]["no_data"] == 0
