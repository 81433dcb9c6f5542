"""Seeding rate by NDVI: seeds/ha between two end points, clamped outside them."""

from __future__ import annotations

import numpy as np
import pytest
from fieldrx.agronomy.ratemodels.registry import RateModelError, rate_models
from fieldrx.agronomy.ratemodels.seeding import seeds_by_ndvi


def test_linear_between_the_end_points_and_clamped_outside() -> None:
    got = seeds_by_ndvi(np.array([0.1, 0.3, 0.55, 0.8, 0.95]), 0.3, 60_000, 0.8, 90_000)
    np.testing.assert_allclose(got, [60_000, 60_000, 75_000, 90_000, 90_000])


def test_its_rates_are_in_the_prescriptions_unit_and_bad_end_points_are_named() -> None:
    m = rate_models().get("seeding_ndvi")
    assert m.rates_in_unit and m.input is not None and m.input.column == "ndvi"
    assert m.rates(np.array([0.55, np.nan]), {}, 2)[0] == pytest.approx(75_000)
    with pytest.raises(RateModelError, match="ndvi_high"):
        m.rates(np.array([0.5]), {"ndvi_low": 0.8, "ndvi_high": 0.3}, 1)
    with pytest.raises(RateModelError, match="unknown parameters"):
        m.rates(np.array([0.5]), {"rate_kg_ha": 3}, 1)
