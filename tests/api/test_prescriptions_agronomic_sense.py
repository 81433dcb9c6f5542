"""Crop defaults with sources, per-nutrient ceilings and the confirmation they need, on PostGIS.

The wheat case: winter wheat, target 8 t/ha, calcium ammonium nitrate 27 % N, IDW from 60
soil samples. With the oilseed-rape parameters (seed 001: e 5.8 -> here wheat's 3.0 but k
0.342 and eq. 20's rape regression) it gave ~440 kg N/ha, twice what the crop needs; with
wheat's own parameter set it must stay inside the published range, and an edit above the
crop's N ceiling must be flagged (count, area, cells) and need confirmation to be sent.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.support import feature, machine_body
from tests.support.plans import API, make_plan
from tests.support.prescriptions import FIELD, all_cells, make_rx

WHEAT_RANGE_KG_N_HA = (150.0, 230.0)  # agronomy.crops: the calibration range, DüV upper end


def wheat_samples_csv(n: int = 60, seed: int = 33) -> str:
    """n samples at random places in FIELD, alkali-hydrolysable N 85..140 mg/kg."""
    (lon0, lat0), (lon1, lat1) = FIELD["coordinates"][0][0], FIELD["coordinates"][0][2]
    rng = np.random.default_rng(seed)
    rows = ["sample_id,lon,lat,alkali_n_mg_kg"]
    for i in range(n):
        lon = lon0 + (lon1 - lon0) * rng.uniform(0.02, 0.98)
        lat = lat0 + (lat1 - lat0) * rng.uniform(0.02, 0.98)
        rows.append(f"W{i},{lon:.8f},{lat:.8f},{rng.uniform(85, 140):.2f}")
    return "\n".join(rows) + "\n"


def wheat_field(client, h) -> tuple[int, dict]:  # noqa: ANN001
    r = client.post(f"{API}/fields", headers=h, json=feature(FIELD, crop="winter wheat"))
    assert r.status_code == 201, r.text
    fid = r.json()["id"]
    r = client.post(
        f"{API}/fields/{fid}/soil-samples",
        headers=h,
        files={"file": ("wheat.csv", wheat_samples_csv(), "text/csv")},
    )
    assert r.status_code == 201, r.text
    assert r.json().get("n_samples", r.json().get("count", 60)) == 60, r.text
    return fid, make_plan(client, h, fid)


def test_every_crop_default_carries_its_source(client, org) -> None:
    cat = client.get(f"{API}/products", headers=org.headers("viewer")).json()
    keys = {c["key"] for c in cat["crops"]}
    assert {"winter_rape", "winter_wheat", "maize", "rice", "winter_barley"} <= keys
    for c in cat["crops"]:
        names = set(c["values"])
        assert {
            "target_yield_t_ha",
            "e_kg_per_100kg",
            "uptake_p2o5_kg_per_100kg",
            "uptake_k2o_kg_per_100kg",
            "k_utilisation",
            "d_intercept_pct",
            "d_slope_pct_mg_kg",
            "ceiling_n_kg_ha",
            "ceiling_p2o5_kg_ha",
            "ceiling_k2o_kg_ha",
        } <= names, c["key"]
        for name, v in c["values"].items():
            assert v["source"].strip() and v["unit"].strip(), (c["key"], name)
    rape = next(c for c in cat["crops"] if c["key"] == "winter_rape")
    assert rape["values"]["k_utilisation"] == {
        "value": 0.342,
        "unit": "fraction",
        "source": "seed 001 eq. 19-21 (winter oilseed rape, Hubei)",
    }
    wheat = next(c for c in cat["crops"] if c["key"] == "winter_wheat")
    # the rape utilisation is no longer wheat's, and says where wheat's comes from
    assert wheat["k_utilisation"] == 0.282 and "Zhang" in wheat["values"]["k_utilisation"]["source"]
    assert "calibrated" in wheat["values"]["d_slope_pct_mg_kg"]["source"]
    assert wheat["ceilings_kg_ha"]["N"] == 230.0


def test_wheat_case_in_range_then_edit_above_ceiling_needs_confirmation(client, org) -> None:
    h = org.headers()
    fid, plan = wheat_field(client, h)
    # no crop in the request: the field's crop ("winter wheat") fills every default
    rx = make_rx(
        client,
        h,
        plan["id"],
        model="nutrient_balance",
        params={"target_yield_kg_ha": 8000},
        product_key="default:can",
        interpolation="idw",
    )
    s = rx["summary"]
    assert s["crop"]["key"] == "winter_wheat" and s["crop_from"] == "field"
    assert s["param_origin"]["k_utilisation"] == "default"
    assert s["param_origin"]["target_yield_kg_ha"] == "default"  # 8 t/ha is wheat's default
    assert "Zhang" in s["param_sources"]["k_utilisation"]
    lo, hi = WHEAT_RANGE_KG_N_HA
    n_min, n_max = s["rate_min_kg_ha"] * 0.27, s["rate_max_kg_ha"] * 0.27
    assert lo <= n_min <= n_max <= hi, (n_min, n_max)
    assert lo <= s["nutrients_kg_ha"]["N"] <= hi
    assert s["plausibility"]["above_ceiling"]["count"] == 0
    assert s["attention"]["count"] == 0

    # an override is recorded as such
    over = make_rx(
        client,
        h,
        plan["id"],
        model="nutrient_balance",
        params={"target_yield_kg_ha": 8000, "k_utilisation": 0.342},
        product_key="default:can",
        interpolation="idw",
        crop="winter_wheat",
    )
    assert over["summary"]["param_origin"]["k_utilisation"] == "override"
    assert "overrides 0.282" in over["summary"]["param_sources"]["k_utilisation"]
    assert over["summary"]["param_origin"]["e_kg_per_100kg"] == "default"

    # edits push 3 cells to 950 kg/ha CAN = 256.5 kg N/ha > wheat's 230
    cells = all_cells(client, h, rx["id"])
    pick = [c["properties"] for c in cells[:3]]
    r = client.post(
        f"{API}/prescriptions/{rx['id']}/edits",
        headers=h,
        json={"cells": [{"seq": p["seq"], "rate_kg_ha": 950} for p in pick], "note": "push"},
    )
    assert r.status_code in (200, 201), r.text
    cur = client.get(f"{API}/prescriptions/{rx['id']}", headers=h).json()["summary"]
    above = cur["plausibility"]["above_ceiling"]
    area = sum(p["area_m2"] for p in pick)
    assert above["count"] == 3 and above["area_m2"] == pytest.approx(area, abs=0.01)
    assert sorted(above["seq"]) == sorted(p["seq"] for p in pick)
    assert above["nutrients"]["N"]["max_kg_ha"] == pytest.approx(256.5)
    assert cur["flagged"]["above_nutrient_ceiling"] == 3
    assert cur["attention"]["count"] == 3

    body = machine_body("wheat spreader", speed_min_m_s=1.2, speed_max_m_s=1.5)
    m = client.post(f"{API}/machines", headers=h, json=body)
    assert m.status_code == 201, m.text
    job = {"prescription_id": rx["id"], "machine_id": m.json()["id"]}
    r = client.post(f"{API}/jobs", headers=h, json=job)
    assert r.status_code == 409, r.text
    err = r.json()
    assert err["where"] == "confirm_flagged"
    assert err["flagged"]["count"] == 3 and err["flagged"]["above_nutrient_ceiling"] == 3
    assert err["flagged"]["area_m2"] == pytest.approx(area, abs=0.01)
    assert "3 above a nutrient ceiling" in err["detail"]
    r = client.post(f"{API}/jobs", headers=h, json={**job, "confirm_flagged": True})
    assert r.status_code == 201, r.text
    sent = r.json()
    assert sent["flagged_cells"] == 3 and sent["flagged_confirmed"] is True
    assert "3 above a nutrient ceiling" in sent["events"][0]["note"]


def test_organisation_ceiling_flags_model_output_and_zone_paint(client, make_org) -> None:
    org = make_org()
    h = org.headers()
    r = client.put(
        f"{API}/ceilings",
        headers=org.headers("admin"),
        json={"ceilings_kg_ha": {"winter_wheat": {"N": 170}}, "curve_share_max": 0.25},
    )
    assert r.status_code == 200, r.text
    eff = r.json()["effective"]["winter_wheat"]["N"]
    assert eff == {"kg_ha": 170.0, "source": "organisation setting"}
    assert r.json()["effective"]["maize"]["N"]["kg_ha"] == 200.0  # others keep theirs
    bad = client.put(
        f"{API}/ceilings", headers=org.headers("admin"), json={"ceilings_kg_ha": {"x": {"N": 1}}}
    )
    assert bad.status_code == 422 and bad.json()["where"] == "ceilings_kg_ha.x"
    assert client.put(f"{API}/ceilings", headers=org.headers("viewer"), json={}).status_code == 403

    _, plan = wheat_field(client, h)
    rx = make_rx(
        client,
        h,
        plan["id"],
        model="nutrient_balance",
        params={"target_yield_kg_ha": 8000},
        product_key="default:can",
        crop="winter_wheat",
    )
    s = rx["summary"]
    above = s["plausibility"]["above_ceiling"]
    cells = all_cells(client, h, rx["id"])
    over = [c["properties"] for c in cells if c["properties"]["rate_kg_ha"] * 0.27 > 170]
    assert over and above["count"] == len(over)
    assert above["area_m2"] == pytest.approx(sum(p["area_m2"] for p in over), abs=0.01)
    assert all("above_nutrient_ceiling" in p["flags"] for p in over)
    assert above["nutrients"]["N"]["source"] == "organisation setting"

    # painting the whole field down to 600 kg/ha (162 kg N) clears every ceiling flag
    ring = FIELD["coordinates"][0]
    pad = [
        [x + (0.001 if i in (1, 2) else -0.001), y + (0.001 if i in (2, 3) else -0.001)]
        for i, (x, y) in enumerate(ring[:4])
    ]
    zone = {"type": "Polygon", "coordinates": [[*pad, pad[0]]]}
    r = client.post(
        f"{API}/prescriptions/{rx['id']}/edits",
        headers=h,
        json={"zone": zone, "rate_kg_ha": 600, "note": "down"},
    )
    assert r.status_code in (200, 201), r.text
    cur = client.get(f"{API}/prescriptions/{rx['id']}", headers=h).json()["summary"]
    assert cur["plausibility"]["above_ceiling"]["count"] == 0
    assert cur["attention"]["count"] == 0


def test_ndvi_curve_cap_share_is_flagged(client, org) -> None:
    """An NDVI prescription whose input sits below the curve's low end on most of the field
    (seed 000: NDVI <= 0.24 -> 375 kg/ha) puts that share at the cap: flagged, counted."""
    h = org.headers()
    (lon0, lat0), (lon1, lat1) = FIELD["coordinates"][0][0], FIELD["coordinates"][0][2]
    rows = ["sample_id,lon,lat,n_mg_kg,ndvi"]
    for i in range(4):
        for j in range(4):
            lon = lon0 + (lon1 - lon0) * (i + 0.5) / 4
            lat = lat0 + (lat1 - lat0) * (j + 0.5) / 4
            rows.append(f"V{i}{j},{lon:.8f},{lat:.8f},100,{0.12 if i < 3 else 0.5}")
    r = client.post(f"{API}/fields", headers=h, json=feature(FIELD))
    fid = r.json()["id"]
    up = client.post(
        f"{API}/fields/{fid}/soil-samples",
        headers=h,
        files={"file": ("ndvi.csv", "\n".join(rows) + "\n", "text/csv")},
    )
    assert up.status_code == 201, up.text
    plan = make_plan(client, h, fid)
    rx = make_rx(client, h, plan["id"], model="ndvi", params={}, interpolation="idw")
    s = rx["summary"]
    cap = s["plausibility"]["curve_limits"]["cap"]
    assert cap["flagged"] and cap["share"] > 0.5, cap
    assert s["flagged"]["at_curve_limit"] == cap["count"]
    assert s["attention"]["count"] >= cap["count"]
    assert s["plausibility"]["curve_limits"]["floor"]["flagged"] is False


def test_form_defaults_come_from_the_field(client, org) -> None:
    h = org.headers()
    fid, plan = wheat_field(client, h)
    d = client.get(f"{API}/fields/{fid}/rx-defaults", headers=h).json()
    assert d["crop"] == "winter_wheat" and d["crop_from"] == "field"
    assert d["product_key"] is None and d["target_yield_t_ha"] is None
    make_rx(
        client,
        h,
        plan["id"],
        model="nutrient_balance",
        params={"target_yield_kg_ha": 7500},
        product_key="default:can",
    )
    d = client.get(f"{API}/fields/{fid}/rx-defaults", headers=h).json()
    assert d["product_key"] == "default:can" and d["target_yield_t_ha"] == 7.5
    assert client.get(f"{API}/fields/{10**7}/rx-defaults", headers=h).status_code == 404
