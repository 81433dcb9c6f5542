"""Response metrics on analytic responses whose figures are known in closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fieldrx_edge.control.metrics import disturbance_metrics, settling_time, step_metrics


def test_first_order_step() -> None:
    tau = 0.2
    t = np.arange(0.0, 3.0, 1e-3)
    y = 1.0 - np.exp(-t / tau)
    m = step_metrics(list(t), list(y), 0.0, 1.0)
    assert m.rise_10_90_s == pytest.approx(tau * math.log(9.0), abs=1e-6)
    assert m.rise_0_90_s == pytest.approx(tau * math.log(10.0), abs=1e-6)
    assert m.settling_2pct_s == pytest.approx(tau * math.log(50.0), abs=1e-6)
    assert m.settling_5pct_s == pytest.approx(tau * math.log(20.0), abs=1e-6)
    assert m.overshoot_pct == 0.0
    end = float(t[-1])
    assert m.iae == pytest.approx(tau * (1 - math.exp(-end / tau)), rel=1e-5)
    assert m.steady_state_error_pct == pytest.approx(100 * math.exp(-end / tau), rel=1e-9)


def test_second_order_overshoot_and_delayed_downward_step() -> None:
    zeta, wn = 0.4, 10.0
    wd = wn * math.sqrt(1 - zeta**2)
    t = np.arange(0.0, 4.0, 1e-4)
    x = 1 - np.exp(-zeta * wn * t) * (
        np.cos(wd * t) + zeta / math.sqrt(1 - zeta**2) * np.sin(wd * t)
    )
    expected = 100 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2))
    # Step 5 -> 3 at t0 = 1 s: scaling, offset, direction and delay must not matter.
    tt = np.concatenate([np.arange(0.0, 1.0, 1e-4), 1.0 + t])
    yy = np.concatenate([np.full(10000, 5.0), 5.0 - 2.0 * x])
    m = step_metrics(list(tt), list(yy), 5.0, 3.0, t0=1.0)
    assert m.overshoot_pct == pytest.approx(expected, rel=1e-4)
    ref = step_metrics(list(t), list(x), 0.0, 1.0)
    assert m.rise_0_90_s == pytest.approx(ref.rise_0_90_s, abs=1e-6)
    assert m.settling_2pct_s == pytest.approx(ref.settling_2pct_s, abs=1e-6)
    # Envelope bound: settling within the classic 4 / (zeta wn) estimate.
    assert ref.settling_2pct_s < 4.0 / (zeta * wn)


def test_never_settling_is_nan_and_flat_is_rejected() -> None:
    t = [0.0, 1.0, 2.0]
    assert math.isnan(settling_time(t, [0.0, 0.5, 0.6], 1.0, 0.02))
    with pytest.raises(ValueError):
        step_metrics(t, [0.0, 0.0, 0.0], 1.0, 1.0)


def test_disturbance_metrics_on_analytic_bump() -> None:
    t = np.arange(0.0, 3.0, 1e-3)
    bump = np.where(t >= 1.0, 0.1 * (t - 1.0) / 0.05 * np.exp(1 - (t - 1.0) / 0.05), 0.0)
    y = 1.0 - bump  # peak deviation 0.1 at 50 ms after the disturbance
    d = disturbance_metrics(list(t), list(y), 1.0, 1.0, 1.0)
    assert d.peak_deviation_pct == pytest.approx(10.0, rel=1e-3)
    assert d.peak_time_s == pytest.approx(0.05, abs=1e-3)
    assert d.recovery_2pct_s > d.peak_time_s
