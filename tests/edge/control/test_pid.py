"""Positional PID: seed 001 reference figures, limits, anti-windup, reset, bumpless retune."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import scipy.signal
from fieldrx_edge.control import PID, make_controller
from fieldrx_edge.control.metrics import step_metrics
from fieldrx_edge.control.simulate import closed_loop, step_at
from fieldrx_edge.plants import seed001_motor
from fieldrx_edge.plants.seeds import SEED001_DEN, SEED001_NUM

from .conftest import metrics_until, seed001_run

PAPER = {"kp": 1.15, "ki": 15.16, "kd": 0.01, "n": 100.0}


def continuous_reference() -> tuple[np.ndarray, np.ndarray]:
    """scipy: closed loop of C(s) = Kp + Ki/s + Kd N s/(s+N) with G(s), seed 001 eq. 4."""
    kp, ki, kd, n = PAPER.values()
    cn = np.polyadd(
        np.polyadd(kp * np.array([1, n, 0]), ki * np.array([0, 1, n])), kd * n * np.array([1, 0, 0])
    )
    num = np.polymul(cn, SEED001_NUM)
    den = np.polyadd(np.polymul([1, n, 0], SEED001_DEN), num)
    t = np.arange(0.0, 1.5, 1e-5)
    _, y = scipy.signal.step((num, den), T=t)
    return t, y


@pytest.mark.slow
def test_paper_gains_reproduce_the_continuous_reference() -> None:
    """Science digest: 0-90 % rise 0.140 s, 2 % settling 0.463 s, overshoot 7.35 % (not 10.33 %)."""
    m = metrics_until(seed001_run(PID(**PAPER), 1e-4, 1.5, None), 1.5)
    assert m.rise_0_90_s == pytest.approx(0.140, abs=0.01)
    assert m.settling_2pct_s == pytest.approx(0.463, abs=0.02)
    assert m.overshoot_pct == pytest.approx(7.35, abs=0.5)
    t, y = continuous_reference()
    ref = step_metrics(list(t), list(y), 0.0, 1.0)
    assert m.rise_0_90_s == pytest.approx(ref.rise_0_90_s, abs=2e-3)
    assert m.settling_2pct_s == pytest.approx(ref.settling_2pct_s, abs=5e-3)
    assert m.overshoot_pct == pytest.approx(ref.overshoot_pct, abs=0.1)


def test_output_limits_hold() -> None:
    pid = PID(5.0, 50.0, 0.1, out_min=-0.5, out_max=1.5)
    tr = seed001_run(pid, 1e-3, 2.0)
    assert max(tr.u) == 1.5 and min(tr.u) >= -0.5
    with pytest.raises(ValueError):
        PID(1.0, out_min=1.0, out_max=0.0)


def test_anti_windup_integrator_stops_while_clamped() -> None:
    dt = 1e-3
    limited = PID(1.0, 10.0, 0.0, out_min=0.0, out_max=1.0)
    plant = seed001_motor(dt)
    # Unreachable setpoint for 5 s (max output gives 1.34): the integrator must not run away.
    closed_loop(limited, plant, step_at(5.0, 3.0, 0.5), 5.0)
    assert limited.integral <= 1.0 + 1e-9
    tr = closed_loop(limited, plant, 0.5, 2.0)
    m = step_metrics(tr.t, tr.y, tr.y[0], 0.5)
    assert m.settling_2pct_s < 1.0  # recovers at once: no wound-up integral to unwind
    naive = PID(1.0, 10.0, 0.0)  # same loop, limit only in the plant: winds up
    plant2 = seed001_motor(dt, u_min=0.0, u_max=1.0)
    closed_loop(naive, plant2, 3.0, 5.0)
    assert naive.integral > 20.0


def test_reset_gives_identical_replay() -> None:
    pid = PID(**PAPER)
    first = seed001_run(pid, 2e-3, 1.0).u
    pid.reset()
    assert seed001_run(pid, 2e-3, 1.0).u == first


@pytest.mark.parametrize(
    "change",
    [{"kp": 2.0}, {"kd": 0.2, "n": 50.0}, {"ki": 5.0}, {"derivative_on": "measurement"}],
)
def test_parameter_change_is_bumpless(change: dict[str, object]) -> None:
    dt = 1e-3
    pid = PID(**PAPER)
    plant = seed001_motor(dt)
    tr = closed_loop(pid, plant, step_at(0.0, 0.0, 1.0), 0.3)  # mid-transient: e and D non-zero
    y = tr.y[-2]  # the measurement of the last step: unchanged inputs
    twin = copy.deepcopy(pid)
    naive = copy.deepcopy(pid)
    pid.set_params(**change)
    for k, v in change.items():
        setattr(naive, k, v)
    u_twin = twin.step(1.0, y, dt)
    assert pid.step(1.0, y, dt) == pytest.approx(u_twin, abs=1e-12)
    if "ki" not in change:  # a P or D change would jump without the integrator transfer
        assert abs(naive.step(1.0, y, dt) - u_twin) > 1e-3


def test_derivative_on_measurement_has_no_setpoint_kick() -> None:
    on_err = PID(1.0, 0.0, 0.1, n=100.0)
    on_meas = PID(1.0, 0.0, 0.1, n=100.0, derivative_on="measurement")
    for c in (on_err, on_meas):
        c.step(0.0, 0.0, 1e-3)
    assert on_err.step(1.0, 0.0, 1e-3) == pytest.approx(1.0 + 0.1 * 100.0)
    assert on_meas.step(1.0, 0.0, 1e-3) == pytest.approx(1.0)
    raw = PID(0.0, 0.0, 0.1, n=None)
    raw.step(0.0, 0.0, 1e-3)
    assert raw.step(1.0, 0.0, 1e-3) == pytest.approx(0.1 / 1e-3)


def test_factory_names() -> None:
    assert isinstance(make_controller("PID", kp=1.0), PID)
    assert type(make_controller("isp")).__name__ == "IncrementalPID"
    assert type(make_controller("incremental_pid")).__name__ == "IncrementalPID"
    assert type(make_controller("ladrc", wc=10, wo=40, b0=8.9)).__name__ == "LADRC"
    assert type(make_controller("fuzzy_pid", kp=1, ki=0.1, kd=0.1)).__name__ == "FuzzyPID"
    with pytest.raises(ValueError, match="unknown controller"):
        make_controller("bang_bang")
    with pytest.raises(TypeError):
        PID(1.0).set_params(gain=3.0)
