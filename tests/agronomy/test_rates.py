"""Rate models against hand-computed values (seed 001 eq. 19-21, seed 000, eq. 1-3)."""

import numpy as np
import pytest
from fieldrx.agronomy.cells import FLAG_BITS, flag_names
from fieldrx.agronomy.ratemodels.ndvi import ndvi_linear_rate
from fieldrx.agronomy.ratemodels.nutrient_balance import (
    nutrient_balance_rate,
    nutrient_balance_raw,
    soil_correction_coefficient,
)
from fieldrx.agronomy.ratemodels.registry import RateModelError
from fieldrx.agronomy.ratemodels.uniform import uniform_rate
from fieldrx.agronomy.rates import (
    MeterCheck,
    MeterRangeError,
    check_meter_range,
    model_rates,
)
from fieldrx_edge.metering import LinearCalibration


def test_worked_example_science_md():
    # d = (5.57 + 3226.05/100)/100 = 0.378305; F = (145 - 2.25*0.378305*100)/(0.342*0.25)
    d = soil_correction_coefficient(100.0)
    assert d == pytest.approx(0.378305)
    f = nutrient_balance_rate(100.0, 2500.0, 0.25)
    assert f == pytest.approx((145.0 - 85.118625) / 0.0855)
    assert f == pytest.approx(700.367, abs=0.001)


@pytest.mark.parametrize(
    ("n", "expected"),
    [
        (30.0, (145.0 - 67.5) / 0.0855),  # d clamped to 1 below 34.2 mg/kg -> 906.43
        (300.0, (145.0 - 2.25 * 0.163235 * 300) / 0.0855),  # 407.21
        (500.0, (145.0 - 2.25 * 0.120221 * 500) / 0.0855),  # 114.05
        (1000.0, 0.0),  # soil supplies more than the crop needs
    ],
)
def test_nutrient_balance_hand_values(n, expected):
    assert nutrient_balance_rate(n, 2500.0, 0.25) == pytest.approx(expected, rel=1e-6)


def test_nutrient_balance_vectorised_and_expanded_form():
    n = np.array([40.0, 80.0, 120.0, 200.0])
    f = nutrient_balance_rate(n, 3000.0, 0.46)
    # docs/science.md expanded form (valid where d < 1): (e*M - 12.53 n - 7258.6) / (100 k x)
    expanded = (5.8 * 3000 - 12.5325 * n - 7258.6125) / (100 * 0.342 * 0.46)
    np.testing.assert_allclose(f, expanded, rtol=1e-9)
    assert nutrient_balance_raw(1000.0, 2500, 0.25) < 0


def test_correction_coefficient_clamped():
    d = soil_correction_coefficient(np.array([10.0, 34.0, 34.3, 0.0]))
    assert d[0] == 1.0 and d[1] == 1.0 and d[3] == 1.0
    assert d[2] < 1.0


def test_nutrient_balance_parameter_errors():
    with pytest.raises(RateModelError, match="n_fraction"):
        nutrient_balance_rate(100.0, 2500.0, 0.0)
    with pytest.raises(RateModelError, match="target_yield"):
        nutrient_balance_rate(100.0, -1.0, 0.25)


def test_ndvi_linear_seed000():
    v = ndvi_linear_rate(np.array([0.24, 0.65, 0.445, 0.1, 0.9]))
    np.testing.assert_allclose(v, [375.0, 180.0, 277.5, 375.0, 180.0])
    edited = ndvi_linear_rate(
        0.5, ndvi_low=0.3, rate_at_low_kg_ha=400, ndvi_high=0.7, rate_at_high_kg_ha=200
    )
    assert edited == pytest.approx(300.0)
    with pytest.raises(RateModelError):
        ndvi_linear_rate(0.5, ndvi_low=0.7, ndvi_high=0.3)


def test_uniform_and_dispatch():
    np.testing.assert_array_equal(uniform_rate(3, 250.0), [250.0, 250.0, 250.0])
    r = model_rates(
        "nutrient_balance",
        np.array([100.0, np.nan]),
        {"target_yield_kg_ha": 2500, "n_fraction": 0.25},
        2,
    )
    assert r[0] == pytest.approx(700.367, abs=1e-3) and np.isnan(r[1])
    with pytest.raises(RateModelError, match="n_fraction"):
        model_rates("nutrient_balance", np.array([1.0]), {"target_yield_kg_ha": 2500}, 1)
    with pytest.raises(RateModelError, match="unknown model"):
        model_rates("magic", np.array([1.0]), {}, 1)
    with pytest.raises(RateModelError, match="unknown parameters"):
        model_rates("uniform", None, {"rate_kg_ha": 1, "x": 2}, 1)


def test_metering_750_at_9kmh_is_110_8_rpm():
    m = MeterCheck.from_kmh(LinearCalibration(), 2.3, 3.0, 9.0)
    assert m.shaft_rpm(750.0, 9.0 / 3.6) == pytest.approx(110.8, abs=0.05)
    # 300 kg/ha at 3 km/h -> 16.2 r/min: below the 30 r/min floor (docs/science.md erratum)
    assert m.shaft_rpm(300.0, 3.0 / 3.6) == pytest.approx(16.2, abs=0.05)


def test_meter_range_flags_without_changing_rates():
    m = MeterCheck.from_kmh(LinearCalibration(), 2.3, 3.0, 9.0)
    lo, hi = m.range_kg_ha()
    # floor: (237.2*30 - 404.4) / (6 * 2.3 * 3/3.6); ceiling: (237.2*130 - 404.4) / (6 * 2.3 * 2.5)
    assert lo == pytest.approx(6711.6 / (6 * 2.3 * 3 / 3.6))
    assert hi == pytest.approx(30431.6 / (6 * 2.3 * 2.5))
    rates, flags, rng = check_meter_range(np.array([0.0, 300.0, 700.0, 1000.0]), m)
    assert rng == (lo, hi)
    np.testing.assert_allclose(rates, [0.0, 300.0, 700.0, 1000.0])  # stored as asked
    assert [flag_names(f) for f in flags] == [[], ["below_meter_range"], [], ["above_meter_range"]]
    assert flags[1] == FLAG_BITS["below_meter_range"]


def test_meter_range_infeasible_is_an_error():
    m = MeterCheck.from_kmh(LinearCalibration(), 2.3, 1.0, 20.0)
    with pytest.raises(MeterRangeError, match="narrow the speed range"):
        check_meter_range(np.array([500.0]), m)
