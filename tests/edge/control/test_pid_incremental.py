"""Incremental PID with integral separation, seed 000 eq. 11-12."""

from __future__ import annotations

import pytest
from fieldrx_edge.control import IncrementalPID
from fieldrx_edge.control.metrics import step_metrics
from fieldrx_edge.control.simulate import closed_loop
from fieldrx_edge.plants import seed000_shaft
from fieldrx_edge.plants.seeds import SEED000_FEEDBACK_SCALE, SEED000_LOOP_PERIOD_S


def test_eq11_increments_by_hand() -> None:
    c = IncrementalPID(kp=0.15, ki=0.32, kd=0.07, eps=0.7, rule="relative_change")
    # e: 0 -> 10 (|10/10| = 1 > 0.7: no integral), 10 -> 8 (|-2/8| = 0.25: integral)
    u1 = c.step(10.0, 0.0, 0.1)
    assert not c.integrating
    assert u1 == pytest.approx(0.15 * 10 + 0.07 * 10)
    u2 = c.step(10.0, 2.0, 0.1)
    assert c.integrating
    assert u2 - u1 == pytest.approx(0.15 * (8 - 10) + 0.32 * 8 + 0.07 * (8 - 20 + 0))
    c.step(10.0, 10.0, 0.1)  # e = 0: no division by zero, nothing to integrate
    assert not c.integrating


def test_rules_differ() -> None:
    band = IncrementalPID(rule="error_band", eps=0.7)
    band.step(0.5, 0.0, 0.1)  # |e| = 0.5 <= 0.7, although the relative change is 1
    assert band.integrating
    band.step(5.0, 0.0, 0.1)
    assert not band.integrating
    plain = IncrementalPID(rule="none")
    plain.step(5.0, 0.0, 0.1)
    assert plain.integrating
    with pytest.raises(ValueError):
        IncrementalPID(rule="sometimes")


def test_limits_no_windup_and_bumpless() -> None:
    c = IncrementalPID(out_min=0.0, out_max=5.0)
    for _ in range(200):
        u = c.step(100.0, 0.0, 0.1)
    assert u == 5.0
    assert c.step(100.0, 101.0, 0.1) < 5.0  # leaves the limit at once: no wound-up state
    before = c.output
    c.set_params(kp=0.3, ki=0.1, kd=0.0, eps=0.2)
    assert c.output == before
    c.reset()
    assert c.output == 0.0
    c.warm_start(0.78)
    assert c.step(1.0, 1.0, 0.1) == pytest.approx(0.78)


def _seed000_step(rule: str, step: float, time_constant: str) -> float:
    plant = seed000_shaft(1e-3, time_constant=time_constant)
    plant.reset(8.0)
    c = IncrementalPID(rule=rule, out_min=plant.u_min, out_max=plant.u_max)
    c.warm_start(plant.equilibrium_input(8.0))
    tr = closed_loop(
        c,
        plant,
        8.0 + step,
        6.0,
        ctrl_period_s=SEED000_LOOP_PERIOD_S,
        feedback_scale=SEED000_FEEDBACK_SCALE,
    )
    m = step_metrics(tr.t, tr.y, 8.0, 8.0 + step)
    assert abs(m.steady_state_error_pct) < 1.0  # both settle on the target
    return m.overshoot_pct


@pytest.mark.parametrize("time_constant", ["printed", "derived"])
@pytest.mark.parametrize("step", [15.0, 25.0])
def test_integral_separation_overshoots_less_than_plain_incremental(
    step: float, time_constant: str
) -> None:
    isp = _seed000_step("relative_change", step, time_constant)
    pid = _seed000_step("none", step, time_constant)
    assert isp < pid
    assert pid > 1.0
