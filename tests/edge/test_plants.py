"""Discretisation and plants, checked against scipy as an independent reference."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
import scipy.signal
from fieldrx_edge.plants import DiscretePlant, seed000_shaft, seed001_motor, seed002_depth
from fieldrx_edge.plants.linalg import expm, tf2ss, zoh
from fieldrx_edge.plants.seeds import (
    SEED001_DEN,
    SEED001_NUM,
    seed000_motor_den,
    seed002_closed_loop_den,
    seed002_open_loop_gain,
)


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("scale", [1e-3, 1.0, 40.0])
def test_expm_matches_scipy(seed: int, scale: float) -> None:
    a = np.random.default_rng(seed).normal(size=(4, 4)) * scale
    ref = scipy.linalg.expm(a)
    assert np.allclose(expm(a), ref, rtol=1e-11, atol=1e-13 * np.abs(ref).max())


def test_expm_of_nilpotent_chain_is_exact() -> None:
    t = 0.002
    a = np.diag([1.0, 1.0], 1) * t
    assert np.allclose(expm(a), [[1, t, t * t / 2], [0, 1, t], [0, 0, 1]], atol=1e-15)


@pytest.mark.parametrize("dt", [1e-4, 2e-3, 0.1])
def test_zoh_matches_scipy_cont2discrete(dt: float) -> None:
    a, b, c, d = tf2ss(SEED001_NUM, SEED001_DEN)
    phi, gam = zoh(a, b, dt)
    ref = scipy.signal.cont2discrete((a, b, c, d), dt, method="zoh")
    assert np.allclose(phi, ref[0], atol=1e-14)
    assert np.allclose(gam, ref[1], atol=1e-14)


def test_tf2ss_matches_scipy_and_rejects_improper() -> None:
    for num, den in [(SEED001_NUM, SEED001_DEN), ((2.6091,), seed002_closed_loop_den())]:
        mine = tf2ss(num, den)
        ref = scipy.signal.tf2ss(num, den)
        for m, r in zip(mine, ref, strict=True):
            assert np.allclose(m, r)
    with pytest.raises(ValueError):
        tf2ss([1.0, 0.0, 0.0], [1.0, 1.0])


def test_plant_step_response_matches_scipy_dlsim() -> None:
    dt = 2e-3
    plant = seed001_motor(dt)
    y = [plant.output] + [plant.step(1.0) for _ in range(500)]
    ss = scipy.signal.tf2ss(SEED001_NUM, SEED001_DEN)
    a, b, c, d, _ = scipy.signal.cont2discrete(ss, dt, method="zoh")
    _, yref = scipy.signal.dstep((a, b, c, d, dt), n=501)
    assert np.allclose(y, np.squeeze(yref[0]), atol=1e-12)


def test_seed001_plant_is_nearly_first_order() -> None:
    plant = seed001_motor(1e-3)
    assert plant.dc_gain() == pytest.approx(0.04603 / 0.03441, rel=1e-9)
    fo = DiscretePlant.from_tf([8.892], [1.0, 6.694], 1e-3)
    a = [plant.step(1.0) for _ in range(1000)]
    b = [fo.step(1.0) for _ in range(1000)]
    assert max(abs(x - y) for x, y in zip(a, b, strict=True)) < 0.002


def test_saturation_disturbance_and_dead_time() -> None:
    dt = 1e-3
    plant = seed000_shaft(dt)  # 10 ms dead time, 0..5 V
    assert plant.delay_samples == 10
    outs = [plant.step(100.0) for _ in range(12)]
    assert all(v == 0.0 for v in outs[:10])  # nothing before the dead time has passed
    assert outs[10] > 0.0
    sat = seed000_shaft(dt)
    ref = seed000_shaft(dt)
    for _ in range(3000):
        sat.step(100.0)
        ref.step(5.0)
    assert sat.output == pytest.approx(ref.output)  # clamped at 5 V
    dist = seed000_shaft(dt)
    dist.disturbance = -1.0
    for _ in range(3000):
        dist.step(5.0)
    assert dist.output == pytest.approx(ref.output * 4.0 / 5.0, rel=1e-3)
    with pytest.raises(ValueError):
        seed000_shaft(3e-3)  # 10 ms is not a whole number of 3 ms samples


def test_reset_to_equilibrium_holds_output() -> None:
    plant = seed000_shaft(1e-3)
    plant.reset(8.0)
    u = plant.equilibrium_input(8.0)
    for _ in range(500):
        plant.step(u)
    assert plant.output == pytest.approx(8.0, abs=1e-9)
    plant.reset()
    assert plant.output == 0.0


def test_seed000_time_constants_printed_and_derived() -> None:
    assert seed000_motor_den("printed") == (0.00032, 0.16, 1.0)
    a2, a1, _ = seed000_motor_den("derived")
    td = 0.62e-3 / 0.5
    tm = (6.88e-4 + 0.001) * 0.5 / (0.052 * 0.06)
    assert tm == pytest.approx(0.2705, abs=1e-3)  # not the printed 0.16 s
    assert a2 == pytest.approx(td * tm) and a1 == pytest.approx(td + tm)
    assert seed000_shaft(1e-3).dc_gain() == pytest.approx(2.4 * 19.2 * 0.028 * 8.0)
    assert seed000_shaft(1e-3, time_constant="derived").dc_gain() == pytest.approx(
        2.4 / 0.052 * 0.028 * 8.0
    )
    with pytest.raises(ValueError):
        seed000_motor_den("other")


def test_seed002_corrected_closed_loop() -> None:
    k = seed002_open_loop_gain()
    assert k == pytest.approx(2.6091)
    a2, a1, a0 = seed002_closed_loop_den()
    assert (a2, a1) == (0.592, 1.0)
    assert a0 == pytest.approx(0.005672, abs=1e-6)  # erratum: not 1200.186
    assert k * 460.0 == pytest.approx(1200.186)  # what the paper printed instead
    # The corrected loop equals G / (1 + G H) with H = 1 / (L + R): DC gain L + R.
    plant = seed002_depth(1e-3)
    assert plant.dc_gain() == pytest.approx(460.0, rel=1e-9)
    assert plant.u_max == pytest.approx(50.0 / 2.6091)
    assert math.isinf(seed001_motor(1e-3).u_max)
