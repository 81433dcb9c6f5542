"""The uniform model class: one rate everywhere, no per-cell input."""

import numpy as np
import pytest
from fieldrx.agronomy.ratemodels.registry import RateModelError, rate_model


def test_one_rate_without_values() -> None:
    m = rate_model("uniform")
    assert m.input is None and m.curve_kg_ha({"rate_kg_ha": 1}) is None
    np.testing.assert_array_equal(m.rates(None, {"rate_kg_ha": 250}, 3), [250.0] * 3)
    with pytest.raises(RateModelError, match="needs parameter 'rate_kg_ha'"):
        m.rates(None, {}, 1)
    with pytest.raises(RateModelError, match="must be >= 0"):
        m.rates(None, {"rate_kg_ha": -1}, 1)
