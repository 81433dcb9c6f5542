"""The NDVI curve model class (seed 000)."""

import numpy as np
import pytest
from fieldrx.agronomy.ratemodels.registry import RateModelError, rate_model


def test_curve_end_points_and_rates() -> None:
    m = rate_model("ndvi")
    assert m.input is not None and m.input.column == "ndvi"
    r = m.rates(np.array([0.24, 0.65, np.nan]), {}, 3)
    assert r[:2] == pytest.approx([375.0, 180.0]) and np.isnan(r[2])
    assert m.curve_kg_ha({}) == (375.0, 180.0)
    assert m.curve_kg_ha({"rate_at_low_kg_ha": 300}) == (300.0, 180.0)
    with pytest.raises(RateModelError, match="unknown parameters"):
        m.rates(np.array([0.3]), {"ndvi_mid": 0.4}, 1)
