"""Kalman speed filter, sliding-window mean, lag compensation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fieldrx_edge.estimate import KalmanSpeedFilter, SlidingWindowMean, lag_time_s, look_ahead
from hypothesis import given, settings
from hypothesis import strategies as st


def gnss_speeds(
    seed: int, speed: float = 1.5, hz: float = 10.0, sigma_pct: float = 2.5
) -> np.ndarray:
    """120 m at 1.5 m/s (seed 001 sec. 2.2) sampled at 10 Hz with white speed noise."""
    n = int(120.0 / speed * hz)
    return speed * (1.0 + np.random.default_rng(seed).normal(0.0, sigma_pct / 100.0, n))


def band_pct(values: np.ndarray, truth: float) -> tuple[float, float]:
    err = (values / truth - 1.0) * 100.0
    return float(err.min()), float(err.max())


def test_gain_converges_to_the_riccati_fixed_point() -> None:
    kf = KalmanSpeedFilter()
    for z in gnss_speeds(0)[:200]:
        kf.update(float(z))
    # P = (1 - K)(P + Q), K = (P + Q) / (P + Q + R): P^2 + Q P - Q R = 0.
    p = (-0.01 + math.sqrt(0.01**2 + 4 * 0.01 * 0.2)) / 2
    assert kf.gain == pytest.approx((p + 0.01) / (p + 0.01 + 0.2), rel=1e-9)
    assert kf.gain == pytest.approx(0.2, abs=0.01)  # "converges to 0.2" (docs/science.md)


def test_first_estimate_is_the_first_measurement() -> None:
    kf = KalmanSpeedFilter()
    assert kf.update(1.43) == 1.43  # not -100 % as with x0 = 0
    assert kf.update(1.43) == pytest.approx(1.43)


@pytest.mark.parametrize("seed", range(5))
def test_band_reduced_to_within_3_8_percent(seed: int) -> None:
    z = gnss_speeds(seed)
    lo, hi = band_pct(z, 1.5)
    assert lo < -6.0 and hi > 6.0 and max(-lo, hi) > 7.5  # raw band of about +-8.5 %
    kf = KalmanSpeedFilter()
    f = np.array([kf.update(float(v)) for v in z])
    # After a 1 s warm-up (10 fixes): the first estimate *is* the first raw fix, so its error
    # can be anything in the raw band until the filter has averaged a few fixes.
    flo, fhi = band_pct(f[10:], 1.5)
    assert -3.8 <= flo and fhi <= 3.8


def test_gross_outlier_is_gated_and_a_real_jump_is_accepted() -> None:
    kf = KalmanSpeedFilter()
    for _ in range(50):
        kf.update(1.5)
    assert kf.update(9.0) == pytest.approx(1.5)  # multipath spike: rejected
    assert kf.last_rejected and kf.rejected_total == 1
    assert kf.update(1.5) == pytest.approx(1.5)
    # A real jump beyond the gate (2.5 m/s -> stop): three rejections in a row, then the
    # filter trusts the receiver again.
    kf.reset()
    for _ in range(50):
        kf.update(2.5)
    outs = [kf.update(0.0) for _ in range(3)]
    assert outs[:2] == pytest.approx([2.5, 2.5])
    assert outs[-1] == 0.0
    ungated = KalmanSpeedFilter(gate_sigma=None)
    ungated.update(1.5)
    assert ungated.update(9.0) > 1.5
    with pytest.raises(ValueError):
        kf.update(float("nan"))
    kf.reset()
    assert kf.value is None


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=1, max_size=80),
    st.integers(1, 20),
)
def test_sliding_mean_equals_the_direct_mean(xs: list[float], window: int) -> None:
    f = SlidingWindowMean(window)
    for k, x in enumerate(xs):
        got = f.update(x)
        ref = sum(xs[max(0, k - window + 1) : k + 1]) / min(k + 1, window)
        assert got == pytest.approx(ref, rel=1e-9, abs=1e-9)


def test_sliding_mean_does_not_drift() -> None:
    f = SlidingWindowMean(15)
    for k in range(40_000):
        f.update(1e9 if k % 2 else -1e9)
    for _ in range(15):
        f.update(0.5)
    assert f.value == 0.5  # exact: the running sum is re-synchronised
    assert len(f) == 15
    with pytest.raises(ValueError):
        SlidingWindowMean(0)


def test_lag_time_eq16() -> None:
    assert lag_time_s(3.8, 9.0) == pytest.approx(1.52)  # 2.5 m/s * 1.52 s = 3.8 m
    with pytest.raises(ValueError):
        lag_time_s(1.0, 0.0)


@pytest.mark.parametrize(
    ("heading_deg", "dx", "dy"),
    [(0, 0, 1), (90, 1, 0), (180, 0, -1), (270, -1, 0), (45, 0.7071, 0.7071)],
)
def test_look_ahead_moves_along_course_over_ground(
    heading_deg: float, dx: float, dy: float
) -> None:
    x, y = look_ahead(100.0, 200.0, math.radians(heading_deg), 2.5, 1.52)
    assert x == pytest.approx(100.0 + 3.8 * dx, abs=1e-3)
    assert y == pytest.approx(200.0 + 3.8 * dy, abs=1e-3)


def test_look_ahead_offsets() -> None:
    # Heading north; outlet 2 m behind the antenna and 1 m to the right (east).
    x, y = look_ahead(0.0, 0.0, 0.0, 2.0, 1.0, forward_offset_m=-2.0, lateral_offset_m=1.0)
    assert (x, y) == pytest.approx((1.0, 0.0))
    # Heading east: right is south.
    x, y = look_ahead(0.0, 0.0, math.pi / 2, 0.0, 1.0, lateral_offset_m=1.0)
    assert (x, y) == pytest.approx((0.0, -1.0))
