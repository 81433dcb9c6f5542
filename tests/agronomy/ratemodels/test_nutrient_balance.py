"""The nutrient-balance model class (seed 001 eq. 19-21); the formula's own values are in
tests/agronomy/test_rates.py."""

import numpy as np
import pytest
from fieldrx.agronomy.ratemodels.nutrient_balance import NutrientBalance, nutrient_balance_rate
from fieldrx.agronomy.ratemodels.registry import RateModelError, rate_model


def test_worked_example_and_defaults() -> None:
    m = rate_model("nutrient_balance")
    assert isinstance(m, NutrientBalance) and m.crop_defaults
    assert m.input is not None and m.input.column == "n_mg_kg"
    r = m.rates(np.array([100.0, np.nan]), {"target_yield_kg_ha": 2500, "n_fraction": 0.25}, 2)
    assert r[0] == pytest.approx(700.367, abs=1e-3) and np.isnan(r[1])
    assert m.default("k_utilisation") == 0.342


def test_parameters_without_default_are_required() -> None:
    m = rate_model("nutrient_balance")
    with pytest.raises(RateModelError, match="needs parameter 'n_fraction'"):
        m.rates(np.array([1.0]), {"target_yield_kg_ha": 2500}, 1)
    explicit = m.rates(
        np.array([80.0]),
        {"target_yield_kg_ha": 3000, "n_fraction": 0.46, "d_slope_pct_mg_kg": 0.0},
        1,
    )
    assert explicit[0] == pytest.approx(
        float(nutrient_balance_rate(80.0, 3000, 0.46, soil_d=(5.57, 0.0)))
    )
