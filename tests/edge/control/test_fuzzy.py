"""Fuzzy PID (seed 002 sec. 2.3): inference, lookup accuracy, tuned loop, interface."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from fieldrx_edge.control import PID, FuzzyPID
from fieldrx_edge.control.fuzzy import RULES_DKD, RULES_DKI, RULES_DKP, mamdani, surface
from fieldrx_edge.control.metrics import step_metrics
from fieldrx_edge.control.simulate import closed_loop
from fieldrx_edge.depth import DEPTH_PID_GAINS, DEPTH_U_LIMIT, STEP_TUNED_FUZZY_FACTORS
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
            **DEPTH_PID_GAINS,
            **STEP_TUNED_FUZZY_FACTORS,
            out_min=-DEPTH_U_LIMIT,
            out_max=DEPTH_U_LIMIT,
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


@pytest.mark.parametrize("n", [None, 20.0, 100.0])
def test_without_adaptation_it_is_the_fixed_pid(n: float | None) -> None:
    # With every output factor 0 (dK = 0, eq. 10: K = K') the fuzzy PID must be the fixed PID
    # with the same gains and derivative filter, sample for sample: the seed 002 comparison
    # (bench/seeds.py) gives both the same base gains. It once filtered ec with gain
    # (1 - e^(-N dt)) / dt instead of N, a derivative 1 % weaker at N 20, 1 ms.
    fixed = PID(**DEPTH_PID_GAINS, n=n, out_min=-DEPTH_U_LIMIT, out_max=DEPTH_U_LIMIT)
    fuzzy = FuzzyPID(
        **DEPTH_PID_GAINS,
        k_dkp=0.0,
        k_dki=0.0,
        k_dkd=0.0,
        n=n,
        out_min=-DEPTH_U_LIMIT,
        out_max=DEPTH_U_LIMIT,
    )
    rng = np.random.default_rng(3)
    y = rng.normal(0.0, 0.5, 3000).cumsum() * 0.05  # a wandering, noisy measurement
    for k, m in enumerate(y):
        r = 1.0 if k > 100 else 0.0
        assert fuzzy.step(r, float(m), 1e-3) == pytest.approx(
            fixed.step(r, float(m), 1e-3), abs=1e-9
        )


def test_table2_adaptation_inside_the_qualified_band() -> None:
    # Sign and size of the adaptation where the depth loop lives: errors within GB/T 20865's
    # +-10 mm band and error rates within the cylinder's 50 mm/s. Table 2 maps e in mm by
    # 6 / 200, so E stays within +-0.3 of ZE: the tables act through Ec alone. At (ZE, ZE)
    # the textbook tables say dKp ZE, dKi ZE, dKd NS (-1 of [-3, 3], x 0.5 = -0.5): Kd drops
    # by about 0.5 (17 % of K'd 3), Kp moves against the sign of ec by at most 0.6 (5 % of
    # K'p 12; an odd function of ec, zero on average) and Ki by at most 0.04.
    c = FuzzyPID(**DEPTH_PID_GAINS)  # Table 2 factors are the defaults
    assert c.deltas(0.0, 0.0) == pytest.approx((0.0, 0.0, -0.5), abs=2e-3)
    grid = [(e, ec) for e in np.linspace(-10, 10, 21) for ec in np.linspace(-50, 50, 41)]
    d = np.array([c.deltas(float(e), float(ec)) for e, ec in grid])
    assert d[:, 2].min() >= -0.65 and d[:, 2].max() <= 1e-9
    assert np.abs(d[:, 0]).max() <= 0.6 + 1e-9 and np.abs(d[:, 1]).max() <= 0.045
    up, down = c.deltas(0.0, -30.0), c.deltas(0.0, 30.0)
    assert up[0] > 0.3 and down[0] < -0.3 and up[0] == pytest.approx(-down[0], abs=1e-6)
