"""Whole-field figures of a rate map, the clamp, the zones table and the diff, on three
cells small enough to check by hand."""

from __future__ import annotations

import numpy as np
import pytest
from fieldrx.agronomy.cells import FLAG_BITS
from fieldrx.agronomy.prescription import (
    PrescriptionError,
    RateRules,
    build_prescription,
    check_breaks,
    clamp_rates,
    class_breaks,
    class_table,
    diff_rates,
)
from fieldrx.agronomy.products import product_figures

RATES = np.array([100.0, 200.0, 400.0])
AREA = np.array([1000.0, 2000.0, 7000.0])  # 1 ha in all
SEQ = np.array([0, 1, 2])


def test_product_figures_by_hand() -> None:
    # product = (100*1000 + 200*2000 + 400*7000) / 1e4 = 330 kg = 0.33 t over 1 ha
    out = product_figures(
        RATES, AREA, {"n_pct": 46, "p2o5_pct": 0, "k2o_pct": 10, "price_per_t": 500}
    )
    assert out["product_t"] == pytest.approx(0.33)
    assert out["nutrients_kg"] == {
        "N": pytest.approx(151.8),
        "P2O5": 0.0,
        "K2O": pytest.approx(33.0),
    }
    assert out["nutrients_kg_ha"]["N"] == pytest.approx(151.8)  # 1 ha
    assert out["cost"] == pytest.approx(165.0)  # 0.33 t x 500
    assert product_figures(RATES, AREA, {"n_pct": 46, "price_per_t": None})["cost"] is None
    assert product_figures(RATES, AREA, None) == {"product_t": pytest.approx(0.33)}


def test_clamp_reports_every_changed_cell() -> None:
    r, fl, rep = clamp_rates(RATES, np.zeros(3, np.uint16), 150.0, 300.0, AREA, SEQ)
    assert r.tolist() == [150.0, 200.0, 300.0]
    assert fl.tolist() == [FLAG_BITS["clamped_min"], 0, FLAG_BITS["clamped_max"]]
    assert (rep["raised"], rep["lowered"], rep["count"], rep["seq"]) == (1, 1, 2, [0, 2])
    assert rep["area_m2"] == 8000.0
    assert (rep["model_min_kg_ha"], rep["model_max_kg_ha"]) == (100.0, 400.0)
    with pytest.raises(PrescriptionError, match="exceeds the maximum"):
        clamp_rates(RATES, np.zeros(3, np.uint16), 300.0, 150.0)


def test_clamp_in_build_then_meter_check_sees_the_clamped_rate() -> None:
    p = build_prescription(
        "uniform", {"rate_kg_ha": 500}, 3,
        rules=RateRules(clamp_max_kg_ha=450), area_m2=AREA, seq=SEQ,
    )
    assert p.rate_kg_ha.tolist() == [450.0] * 3
    assert p.summary(AREA)["clamp"]["lowered"] == 3


def test_zones_table_and_breaks() -> None:
    b = class_breaks(100.0, 400.0, 3)  # 100, 200, 300, 400
    assert b == [100.0, 200.0, 300.0, 400.0]
    t = class_table(RATES, AREA, b)
    # class 1 [100, 200): cell 0; class 2 [200, 300): cell 1; class 3 [300, 400]: cell 2
    assert [r["n_cells"] for r in t] == [1, 1, 1]
    assert [r["area_ha"] for r in t] == [0.1, 0.2, 0.7]
    assert [r["product_t"] for r in t] == pytest.approx([0.01, 0.04, 0.28])
    assert class_breaks(5.0, 5.0, 4) == [5.0, 6.0]
    with pytest.raises(PrescriptionError, match="must increase"):
        check_breaks([1, 3, 2])


def test_diff_by_hand() -> None:
    d = diff_rates(SEQ, RATES, np.array([100.0, 250.0, 300.0]), AREA)
    # cell 1 +50 on 2000 m2 (+10 kg), cell 2 -100 on 7000 m2 (-70 kg)
    assert (d["cells_changed"], d["seq"], d["area_changed_m2"]) == (2, [1, 2], 9000.0)
    assert d["product_kg_delta"] == pytest.approx(-60.0)
    assert (d["max_increase_kg_ha"], d["max_decrease_kg_ha"]) == (50.0, 100.0)
