"""The prescription screen's API on PostGIS: product catalogue, crop
defaults, the agronomist's clamp (reported), whole-field figures, legend classes and the
zones table, version notes, undo / redo (current version) and the diff of two versions.
Every figure is checked against arithmetic written out in the test."""

from __future__ import annotations

import pytest

from tests.support.plans import API
from tests.support.prescriptions import all_cells, make_rx, samples_csv, setup_plan

# seed 001 eq. 19-21 with e 5.8, k 0.342, x 0.25, M 2500:
# n = 100 mg/kg: d = (5.57 + 3226.05/100)/100 = 0.378305, soil N = 2.25 * d * 100 = 85.1186,
# F = (145 - 85.1186) / (0.342 * 0.25) = 59.8814 / 0.0855 = 700.36 kg/ha
WORKED_F = (5.8 * 2500 / 100 - 2.25 * ((5.57 + 3226.05 / 100) / 100) * 100) / (0.342 * 0.25)


def _add_product(client, h, **body) -> dict:
    r = client.post(f"{API}/products", headers=h, json=body)
    assert r.status_code == 201, r.text
    return r.json()


def test_catalogue_defaults_named_by_source_and_org_products(client, make_org) -> None:
    a, b = make_org(), make_org()
    r = client.get(f"{API}/products", headers=a.headers("viewer"))
    assert r.status_code == 200, r.text
    cat = r.json()
    keys = {p["key"]: p for p in cat["products"]}
    assert keys["default:urea"]["n_pct"] == 46.0 and keys["default:urea"]["id"] is None
    assert "seed 001" in keys["default:compound_25n"]["source"]
    rape = next(c for c in cat["crops"] if c["key"] == "winter_rape")
    assert (rape["e_kg_per_100kg"], rape["k_utilisation"]) == (5.8, 0.342)
    assert "seed 001" in rape["source"]

    mine = _add_product(
        client, a.headers(), name="Farm NP 20-10", n_pct=20, p2o5_pct=10, price_per_t=400
    )
    assert mine["key"] == f"org:{mine['id']}" and mine["source"] == "organisation product"
    again = client.post(
        f"{API}/products", headers=a.headers(), json={"name": "Farm NP 20-10", "n_pct": 1}
    )
    assert again.status_code == 409 and "already exists" in again.json()["detail"]
    over = client.post(
        f"{API}/products", headers=a.headers(), json={"name": "x", "n_pct": 60, "k2o_pct": 50}
    )
    assert over.status_code == 422 and "exceeds 100" in over.text
    assert (
        client.post(
            f"{API}/products", headers=a.headers("viewer"), json={"name": "v", "n_pct": 1}
        ).status_code
        == 403
    )
    # another organisation neither lists nor uses it
    other = client.get(f"{API}/products", headers=b.headers()).json()["products"]
    assert mine["key"] not in {p["key"] for p in other}
    plan_b = setup_plan(client, b.headers())
    r = client.post(
        f"{API}/plans/{plan_b['id']}/prescriptions",
        headers=b.headers(),
        json={"model": "uniform", "params": {"rate_kg_ha": 100}, "product_key": mine["key"]},
    )
    assert r.status_code == 422 and "not in this catalogue" in r.json()["detail"]
    assert client.delete(f"{API}/products/{mine['id']}", headers=b.headers()).status_code == 404
    assert client.delete(f"{API}/products/{mine['id']}", headers=a.headers()).status_code == 204


def test_crop_and_product_fill_parameters_and_say_where_from(client, org) -> None:
    """Only the target yield is typed: e and k from the crop, x from the product."""
    h = org.headers()
    plan = setup_plan(client, h, samples_csv([100.0]))
    rx = make_rx(
        client,
        h,
        plan["id"],
        model="nutrient_balance",
        params={"target_yield_kg_ha": 2500},
        crop="winter_rape",
        product_key="default:compound_25n",
        interpolation="idw",
    )
    assert rx["params"]["n_fraction"] == 0.25 and rx["params"]["e_kg_per_100kg"] == 5.8
    assert rx["product"] == "Compound 25 % N (seed 001 example)"
    s = rx["summary"]
    assert s["rate_mean_kg_ha"] == pytest.approx(WORKED_F, abs=0.01)
    # 2500 kg/ha is the crop's own default yield: recorded as the default, not an override
    assert "seed 001" in s["param_sources"]["target_yield_kg_ha"]
    assert s["param_origin"]["target_yield_kg_ha"] == "default"
    assert "seed 001" in s["param_sources"]["e_kg_per_100kg"]
    assert "Compound 25" in s["param_sources"]["n_fraction"]
    assert s["crop"]["key"] == "winter_rape"
    # N per ha = mean rate x 25 % (no price: no cost rather than a guessed one)
    assert s["nutrients_kg_ha"]["N"] == pytest.approx(WORKED_F * 0.25, abs=0.01)
    assert s["cost"] is None

    bad = [
        ({"params": {"target_yield_kg_ha": 2500, "n_fraction": 0.3}}, "disagrees with product"),
        ({"params": {"target_yield_kg_ha": 2500}, "crop": "banana"}, "unknown crop"),
        (
            {"params": {"target_yield_kg_ha": 2500}, "clamp_min_kg_ha": 9, "clamp_max_kg_ha": 1},
            "exceeds",
        ),
    ]
    for extra, msg in bad:
        body = {"model": "nutrient_balance", "product_key": "default:compound_25n", **extra}
        r = client.post(f"{API}/plans/{plan['id']}/prescriptions", headers=h, json=body)
        assert r.status_code == 422 and msg in r.text, (extra, r.text)
    listed = client.get(f"{API}/prescriptions?plan_id={plan['id']}", headers=h).json()
    assert listed["total"] == 1  # nothing half-stored by the refusals


def test_clamp_changes_exactly_the_cells_outside_and_reports_them(client, org) -> None:
    h = org.headers()
    plan = setup_plan(client, h, samples_csv())  # n 60..105 mg/kg: rates ~690..760 kg/ha
    body = {
        "model": "nutrient_balance",
        "params": {"target_yield_kg_ha": 2500, "n_fraction": 0.25},
        "interpolation": "idw",
    }
    free = make_rx(client, h, plan["id"], **body)
    lo = round(free["summary"]["rate_min_kg_ha"] + 10, 1)
    hi = round(free["summary"]["rate_max_kg_ha"] - 10, 1)
    rx = make_rx(client, h, plan["id"], clamp_min_kg_ha=lo, clamp_max_kg_ha=hi, **body)
    before = {c["properties"]["seq"]: c["properties"] for c in all_cells(client, h, free["id"])}
    after = {c["properties"]["seq"]: c["properties"] for c in all_cells(client, h, rx["id"])}
    raised = {s for s, p in before.items() if p["rate_kg_ha"] < lo}
    lowered = {s for s, p in before.items() if p["rate_kg_ha"] > hi}
    assert raised and lowered
    for s, p in after.items():
        if s in raised:
            assert p["rate_kg_ha"] == lo and "clamped_min" in p["flags"]
        elif s in lowered:
            assert p["rate_kg_ha"] == hi and "clamped_max" in p["flags"]
        else:
            assert p["rate_kg_ha"] == pytest.approx(before[s]["rate_kg_ha"])
            assert not {"clamped_min", "clamped_max"} & set(p["flags"])
    c = rx["summary"]["clamp"]
    assert (c["min_kg_ha"], c["max_kg_ha"]) == (lo, hi)
    assert (c["raised"], c["lowered"], c["count"]) == (
        len(raised),
        len(lowered),
        len(raised | lowered),
    )
    assert set(c["seq"]) == raised | lowered
    area = sum(before[s]["area_m2"] for s in raised | lowered)
    assert c["area_m2"] == pytest.approx(area, abs=0.01)
    assert c["model_min_kg_ha"] == pytest.approx(free["summary"]["rate_min_kg_ha"], abs=1e-3)
    assert rx["summary"]["flagged"]["clamped_min"] == len(raised)
    assert (rx["summary"]["rate_min_kg_ha"], rx["summary"]["rate_max_kg_ha"]) == (lo, hi)


def test_summary_figures_classes_notes_diff_and_undo(client, org) -> None:
    h = org.headers()
    plan = setup_plan(client, h)
    prod = _add_product(client, h, name="NP 20-10", n_pct=20, p2o5_pct=10, price_per_t=400)
    rx = make_rx(
        client,
        h,
        plan["id"],
        model="uniform",
        params={"rate_kg_ha": 300},
        product_key=prod["key"],
        note="first pass",
    )
    rid = rx["id"]
    s = rx["summary"]
    area_m2 = s["area_m2"]
    area_ha = area_m2 / 1e4
    # 300 kg/ha over A ha: 300 A kg = 0.3 A t; N 20 % of 300 = 60 kg/ha, P2O5 30 kg/ha;
    # cost 0.3 A t x 400 per t = 120 A
    assert s["product_kg"] == pytest.approx(300 * area_ha, abs=1e-3)
    assert s["product_t"] == pytest.approx(0.3 * area_ha, abs=1e-6)
    assert s["nutrients_kg_ha"] == {"N": 60.0, "P2O5": 30.0, "K2O": 0.0}
    assert s["nutrients_kg"]["N"] == pytest.approx(60 * area_ha, abs=1e-3)
    assert s["cost"] == pytest.approx(120 * area_ha, abs=0.01)
    assert (s["rate_min_kg_ha"], s["rate_mean_kg_ha"], s["rate_max_kg_ha"]) == (300, 300, 300)
    # uniform: one class 300..301 holding the whole field
    assert s["classes"]["breaks_kg_ha"] == [300, 301]
    (row,) = s["classes"]["table"]
    assert row["class"] == 1 and row["n_cells"] == plan["n_cells"]
    assert row["area_ha"] == pytest.approx(area_ha, abs=1e-6)
    assert row["product_t"] == pytest.approx(0.3 * area_ha, abs=1e-6)
    assert rx["versions"][0]["note"] == "first pass"

    cells = {c["properties"]["seq"]: c["properties"] for c in all_cells(client, h, rid)}
    a01 = cells[0]["area_m2"] + cells[1]["area_m2"]
    r = client.post(
        f"{API}/prescriptions/{rid}/edits",
        headers=h,
        json={
            "cells": [{"seq": 0, "rate_kg_ha": 400}, {"seq": 1, "rate_kg_ha": 400}],
            "note": "wet corner",
        },
    )
    assert r.status_code == 201, r.text
    s2 = r.json()["summary"]
    # +100 kg/ha on cells 0 and 1: + 100 * a01 / 1e4 kg, + that / 1000 * 400 cost
    assert s2["product_kg"] == pytest.approx(300 * area_ha + 100 * a01 / 1e4, abs=1e-3)
    assert s2["cost"] == pytest.approx((300 * area_ha + 100 * a01 / 1e4) / 1000 * 400, abs=0.01)
    # the edit keeps v1's breaks and the edited rate gets a class of its own (widening
    # v1's one class to 400 coloured the edited cells like the unedited ones)
    assert s2["classes"]["breaks_kg_ha"] == [300, 301, 400]
    assert [row["n_cells"] for row in s2["classes"]["table"]] == [plan["n_cells"] - 2, 2]
    note = "; edited rates beyond them have a class of their own"
    assert s["classes"]["source"] == "uniform rate: one class"
    assert s2["classes"]["source"] == "uniform rate: one class" + note

    d = client.get(f"{API}/prescriptions/{rid}/diff?from=1&to=2", headers=h)
    assert d.status_code == 200, d.text
    d = d.json()
    assert (d["from_version"], d["to_version"], d["cells_changed"]) == (1, 2, 2)
    assert d["seq"] == [0, 1]
    assert d["area_changed_m2"] == pytest.approx(a01, abs=1e-3)
    assert d["product_kg_delta"] == pytest.approx(100 * a01 / 1e4, abs=1e-3)
    assert d["cost_delta"] == pytest.approx(100 * a01 / 1e4 / 1000 * 400, abs=0.01)
    assert (d["max_increase_kg_ha"], d["max_decrease_kg_ha"]) == (100, 0)
    back = client.get(f"{API}/prescriptions/{rid}/diff?from=2&to=1", headers=h).json()
    assert back["product_kg_delta"] == pytest.approx(-d["product_kg_delta"], abs=1e-3)
    assert client.get(f"{API}/prescriptions/{rid}/diff?from=1&to=7", headers=h).status_code == 404

    # notes: stored with the version, editable afterwards
    r = client.patch(f"{API}/prescriptions/{rid}/versions/1", headers=h, json={"note": "baseline"})
    assert r.status_code == 200 and r.json()["note"] == "baseline"
    vs = client.get(f"{API}/prescriptions/{rid}/versions", headers=h).json()["items"]
    assert [v["note"] for v in vs] == ["baseline", "wet corner"]

    # undo / redo move the current version; no version changes
    r = client.put(f"{API}/prescriptions/{rid}/current", headers=h, json={"version": 1})
    assert r.status_code == 200 and r.json()["current_version"] == 1
    assert r.json()["summary"]["product_kg"] == s["product_kg"]
    r = client.put(f"{API}/prescriptions/{rid}/current", headers=h, json={"version": 2})
    assert (
        r.json()["current_version"] == 2 and r.json()["summary"]["product_kg"] == s2["product_kg"]
    )
    assert (
        client.put(f"{API}/prescriptions/{rid}/current", headers=h, json={"version": 9}).status_code
        == 404
    )
    viewer = client.put(
        f"{API}/prescriptions/{rid}/current", headers=org.headers("viewer"), json={"version": 1}
    )
    assert viewer.status_code == 403


def test_legend_classes_editable_per_version(client, org) -> None:
    h = org.headers()
    plan = setup_plan(client, h, samples_csv())
    rx = make_rx(
        client,
        h,
        plan["id"],
        model="nutrient_balance",
        params={"target_yield_kg_ha": 2500, "n_fraction": 0.25},
        interpolation="idw",
        class_count=4,
    )
    rid, s = rx["id"], rx["summary"]
    b = s["classes"]["breaks_kg_ha"]
    lo, hi = s["rate_min_kg_ha"], s["rate_max_kg_ha"]
    assert (
        len(b) == 5 and b[0] == pytest.approx(lo, abs=1e-3) and b[-1] == pytest.approx(hi, abs=1e-3)
    )
    assert b[1] - b[0] == pytest.approx((hi - lo) / 4, abs=2e-3)

    def check_table(summary: dict) -> None:
        t = summary["classes"]["table"]
        assert sum(r["n_cells"] for r in t) == summary["n_cells"]
        assert sum(r["area_ha"] for r in t) == pytest.approx(summary["area_ha"], abs=1e-5)
        assert sum(r["product_t"] for r in t) == pytest.approx(
            summary["product_kg"] / 1000, abs=1e-5
        )

    check_table(s)
    # the cells of class 2 by hand
    cells = [c["properties"] for c in all_cells(client, h, rid)]
    in2 = [c for c in cells if b[1] <= c["rate_kg_ha"] < b[2]]
    row2 = s["classes"]["table"][1]
    assert row2["n_cells"] == len(in2)
    assert row2["product_t"] == pytest.approx(
        sum(c["rate_kg_ha"] * c["area_m2"] for c in in2) / 1e7, abs=1e-6
    )

    r = client.patch(
        f"{API}/prescriptions/{rid}/versions/1", headers=h, json={"breaks_kg_ha": [700, 720, 740]}
    )
    assert r.status_code == 200, r.text
    cl = r.json()["summary"]["classes"]
    assert cl["breaks_kg_ha"] == [700, 720, 740] and cl["source"] == "set by user"
    check_table(r.json()["summary"])
    bad = client.patch(
        f"{API}/prescriptions/{rid}/versions/1", headers=h, json={"breaks_kg_ha": [700, 690]}
    )
    assert bad.status_code == 422 and "must increase" in bad.text
    # what the zones table shows: words, not the request's key
    assert bad.json()["detail"].startswith("class breaks (kg/ha) must increase")
    again = client.get(f"{API}/prescriptions/{rid}/versions/1", headers=h).json()
    assert again["summary"]["classes"]["breaks_kg_ha"] == [700, 720, 740]  # unchanged by the 422
    r = client.patch(f"{API}/prescriptions/{rid}/versions/1", headers=h, json={"class_count": 3})
    assert len(r.json()["summary"]["classes"]["breaks_kg_ha"]) == 4


def test_edit_is_based_on_the_version_on_screen(client, org) -> None:
    """Editing v1 while v2 is current makes v3 from v1's rates (not v2's)."""
    h = org.headers()
    plan = setup_plan(client, h)
    rid = make_rx(client, h, plan["id"], model="uniform", params={"rate_kg_ha": 300})["id"]
    url = f"{API}/prescriptions/{rid}/edits"
    r = client.post(url, headers=h, json={"cells": [{"seq": 0, "rate_kg_ha": 500}]})
    assert r.json()["new_version"] == 2
    r = client.post(
        url, headers=h, json={"cells": [{"seq": 1, "rate_kg_ha": 400}], "based_on_version": 1}
    )
    assert r.status_code == 201, r.text
    assert r.json()["new_version"] == 3 and r.json()["summary"]["based_on_version"] == 1
    v3 = {
        c["properties"]["seq"]: c["properties"]["rate_kg_ha"] for c in all_cells(client, h, rid, 3)
    }
    assert (v3[0], v3[1]) == (300, 400)
    r = client.post(
        url, headers=h, json={"cells": [{"seq": 1, "rate_kg_ha": 400}], "based_on_version": 8}
    )
    assert r.status_code == 404 and "no version 8" in r.json()["detail"]


def test_edits_beyond_the_breaks_each_get_a_class_the_note_said_once() -> None:
    import numpy as np
    from fieldrx.services.prescriptions.classes import auto_classes, inherited_classes

    area = np.full(6, 10.0)
    v1 = auto_classes(np.full(6, 300.0), area, 6)
    v2 = inherited_classes(np.array([400.0, 400, 300, 300, 300, 300]), area, v1)
    v3 = inherited_classes(np.array([400.0, 400, 450, 300, 300, 300]), area, v2)
    assert v3["breaks_kg_ha"] == [300, 301, 400.001, 450]  # the 400s stay in their class
    assert [r["n_cells"] for r in v3["table"]] == [3, 2, 1]
    note = "; edited rates beyond them have a class of their own"
    assert v3["source"] == "uniform rate: one class" + note
    low = inherited_classes(np.array([250.0, 300, 300, 300, 300, 300]), area, v1)
    assert low["breaks_kg_ha"] == [250, 300, 301]
    assert [r["n_cells"] for r in low["table"]] == [1, 5]
