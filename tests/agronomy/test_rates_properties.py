"""Properties that must hold for any input (hypothesis, modest example counts)."""

import numpy as np
import pytest
from fieldrx.agronomy.interpolate import idw
from fieldrx.agronomy.ratemodels.nutrient_balance import nutrient_balance_rate
from fieldrx.agronomy.rates import MeterCheck, check_meter_range
from fieldrx_edge.metering import LinearCalibration
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

# hypothesis searches hundreds of cases per test: minutes, not seconds (make check skips)
pytestmark = pytest.mark.slow

finite = st.floats(0.0, 1000.0, allow_nan=False)


@settings(max_examples=50, deadline=None)
@given(n1=finite, n2=finite, m=st.floats(500, 6000), x=st.floats(0.05, 0.6))
def test_nutrient_balance_never_increases_with_soil_n(n1, n2, m, x):
    lo, hi = sorted((n1, n2))
    f_lo, f_hi = nutrient_balance_rate(np.array([lo, hi]), m, x)
    assert f_hi <= f_lo + 1e-9 and f_hi >= 0.0


@settings(max_examples=40, deadline=None)
@given(
    pts=arrays(np.float64, (12, 2), elements=st.floats(0, 100)),
    vals=arrays(np.float64, 12, elements=st.floats(0, 500)),
    targets=arrays(np.float64, (8, 2), elements=st.floats(-20, 120)),
    power=st.floats(0.5, 4.0),
)
def test_idw_is_a_convex_combination(pts, vals, targets, power):
    res = idw(targets, pts, vals, power=power)
    assert (res.values >= vals.min() - 1e-9).all() and (res.values <= vals.max() + 1e-9).all()


@settings(max_examples=50, deadline=None)
@given(rates=arrays(np.float64, 20, elements=st.floats(0, 3000)))
def test_meter_check_never_changes_a_rate_and_flags_every_unmeterable_one(rates):
    m = MeterCheck.from_kmh(LinearCalibration(), 2.3, 3.0, 9.0)
    lo, hi = m.range_kg_ha()
    out, flags, _ = check_meter_range(rates, m)
    np.testing.assert_array_equal(out, rates)
    meterable = (rates == 0) | ((rates >= lo) & (rates <= hi))
    assert ((flags != 0) == ~meterable).all()  # every unmeterable rate is flagged, nothing else
