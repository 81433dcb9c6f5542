"""Fuzzy PID (seed 002 sec. 2.3): inference, lookup accuracy, tuned loop, interface."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from fieldrx_edge.control import PID, FuzzyPID
from fieldrx_edge.control.fuzzy import RULES_DKD, RULES_DKI, RULES_DKP, mamdani, surface
from fieldrx_edge.control.metrics import step_metrics
from fieldrx_edge.control.simulate import closed_loop
from fieldrx_edge.depth import DEPTH_FUZZY_FACTORS, DEPTH_PID_GAINS, DEPTH_U_LIMIT
from fieldrx_edge.plants import seed002_depth


def test_single_rule_centroids() -> None:
    # E = NB, Ec = NB fires only (NB, NB): dKp = PB, whose triangle is cut at +3: centroid 8/3.
    assert mamdani(RULES_DKP, np.array([-6.0]), np.array([-6.0]))[0] == pytest.approx(
        8 / 3, abs=5e-3
    )
    # At (ZE, ZE): dKp ZE, dKi ZE, dKd NS (centroid -1).
    z = np.array([0.0])
    assert mamdani(RULES_DKP, z, z)[0] == pytest.approx(0.0, abs=1e-12)
    assert mamdani(RULES_DKI, z, z)[0] == pytest.approx(0.0, abs=1e-12)
    assert mamdani(RULES_DKD, z, z)[0] == pytest.approx(-1.0, abs=1e-3)


def test_aggregation_is_max_not_sum() -> None:
    # E = -5 (NB 0.5, NM 0.5), Ec = -6 (NB): both rules say PB at strength 0.5. MAX keeps the
    # PB triangle cut at 0.5 (centroid 2.6111); a sum would cut it at 1.0 (centroid 2.6667).
    got = mamdani(RULES_DKP, np.array([-5.0]), np.array([-6.0]))[0]
    assert got == pytest.approx(0.97917 / 0.375, abs=5e-3)  # 601-point discrete centroid


def test_lookup_matches_exact_inference() -> None:
    c = FuzzyPID(1.0, 1.0, 1.0, k_e=1.0, k_ec=1.0, k_dkp=1.0, k_dki=1.0, k_dkd=1.0)
    rng = np.random.default_rng(7)
    pts = rng.uniform(-7.0, 7.0, size=(300, 2))  # beyond +-6 too: inputs are clamped
    exact = [mamdani(r, pts[:, 0], pts[:, 1]) for r in (RULES_DKP, RULES_DKI, RULES_DKD)]
    for k, (e, ec) in enumerate(pts):
        got = c.deltas(float(e), float(ec))
        for out, ref in zip(got, exact, strict=True):
            assert out == pytest.approx(ref[k], abs=0.06)
    assert len(surface(RULES_DKP)) == 49


def test_quantisation_and_output_factors_scale() -> None:
    c = FuzzyPID(1.0, 1.0, 1.0)  # Table 2 factors
    # e = 200 -> E = 6, ec = -50 -> Ec = -6 (Table 2 domains); dKp = table (PB, NB) = ZE.
    dkp, dki, dkd = c.deltas(200.0, -50.0)
    assert dkp == pytest.approx(0.0, abs=1e-9)
    assert abs(dki) <= 0.06 and abs(dkd) <= 1.5
    d_big = c.deltas(1e6, -1e6)
    assert d_big == pytest.approx((dkp, dki, dkd))  # clamped to the universe


def _depth_run(ctrl: object) -> object:
    plant = seed002_depth(1e-3)
    tr = closed_loop(ctrl, plant, 1.0, 5.0)  # type: ignore[arg-type]
    return step_metrics(tr.t, tr.y, 0.0, 1.0)


def test_tuned_fuzzy_pid_is_at_least_as_good_as_fixed_pid() -> None:
    fixed = _depth_run(
        PID(**DEPTH_PID_GAINS, n=None, out_min=-DEPTH_U_LIMIT, out_max=DEPTH_U_LIMIT)
    )
    fuzzy = _depth_run(
        FuzzyPID(
            **DEPTH_PID_GAINS, **DEPTH_FUZZY_FACTORS, out_min=-DEPTH_U_LIMIT, out_max=DEPTH_U_LIMIT
        )
    )
    assert fuzzy.overshoot_pct <= fixed.overshoot_pct
    assert fuzzy.settling_2pct_s <= fixed.settling_2pct_s
    assert fuzzy.iae <= fixed.iae


def test_limits_anti_windup_reset_bumpless() -> None:
    c = FuzzyPID(12.0, 0.05, 3.0, out_min=-1.0, out_max=1.0)
    for _ in range(5000):
        u = c.step(100.0, 0.0, 1e-3)
    assert u == 1.0
    assert c._integ < 1.0 + 1e-9  # conditional integration held it
    assert c.step(100.0, 200.0, 1e-3) < 1.0
    c.reset()
    assert c.output == 0.0 and c.gains == (12.0, 0.05, 3.0)
    plant = seed002_depth(1e-3)
    tr = closed_loop(c, plant, 1.0, 0.3)
    y = tr.y[-2]
    twin = copy.deepcopy(c)
    c.set_params(kp=6.0, kd=1.0)
    # Unchanged inputs: the derivative term vanishes, P + I must match the twin's output.
    assert c.step(1.0, y, 1e-3) == pytest.approx(twin.step(1.0, y, 1e-3), abs=1e-9)
