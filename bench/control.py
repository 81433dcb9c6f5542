"""The three papers' control experiments, re-simulated honestly, beside the papers' figures.

Run: .venv/bin/python bench/control.py [--tune]

Prints, per experiment, the paper's figures next to ours (10-90 % and 0-90 %
rise, 2 % and 5 % settling, overshoot, steady-state error, peak deviation and
recovery after a step disturbance), writes step-response PNGs under
bench/out/, prints the cost of one controller ``step()`` in microseconds
(with a trivial Python call measured in the same run as the baseline), and
ends with one JSON line of the key figures. ``--tune`` re-runs the grid
searches behind the seed 002 tuning (about 20 s).

Design notes (the numbers below are what this script prints):

Seed 001 LADRC design. The motor G(s) is first order in effect
(8.892 / (s + 6.694), docs/science.md), so FieldRx uses a *first-order* LADRC:
b0 = 8.892 (the plant's high-frequency gain), controller bandwidth
wc = 20 rad/s (ideal closed loop wc / (s + wc): 10-90 % rise 2.2 / wc =
0.11 s, 2 % settling 3.9 / wc = 0.20 s, no overshoot), observer bandwidth
wo = 5 wc = 100 rad/s, at the paper's 2 ms loop period (wo T = 0.2) with the
discrete current-estimator ESO (poles at exp(-wo T)). The initial command on a
unit step is wc / b0 = 2.25, about the PID's own initial kick (Kp + Kd N =
2.15), so the comparison does not buy speed with actuator effort.

Seed 000 loop. The paper leaves the chaining, sample time and units open.
We put driver, motor, reducer and encoder gain in the forward path (command in
V -> shaft r/min, 10.3 r/min per V, 0-5 V driver input), let the incremental
PID act on encoder volts (speed / 8, eq. 10) at a 0.1 s period with the
printed per-sample gains; see plants/seeds.py for why.

Seed 002 tuning. Fixed PID: grid search over Kp {2..12}, Ki {0.05..0.5},
Kd {1..4} for the least IAE with <= 2 % overshoot on the unit step of the
corrected loop, giving Kp 12, Ki 0.05, Kd 3 (at the edge of the grid: with no
noise or actuator limit in play, higher gain keeps winning, so we stop at a
practical gain). The fuzzy PID uses these as K' and only its factors are
tuned: a grid over k_e, k_ec, k_dkp, k_dkd, k_dki for the least IAE among the
settings no worse than the fixed PID in overshoot, settling and IAE.
"""

import argparse
import itertools
import json
import math
import os
import time

import numpy as np
import scipy.signal
from fieldrx_edge.control import LADRC, PID, FuzzyPID, IncrementalPID
from fieldrx_edge.control.metrics import disturbance_metrics, step_metrics
from fieldrx_edge.control.simulate import closed_loop
from fieldrx_edge.depth import (
    DEPTH_PID_GAINS,
    DEPTH_U_LIMIT,
    STEP_TUNED_FUZZY_FACTORS,
    TABLE2_FACTORS,
)
from fieldrx_edge.estimate import KalmanSpeedFilter
from fieldrx_edge.plants import seed000_shaft, seed001_motor, seed002_depth
from fieldrx_edge.plants.seeds import (
    SEED000_FEEDBACK_SCALE,
    SEED000_LOOP_PERIOD_S,
    SEED001_DEN,
    SEED001_NUM,
)

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "out")
LADRC_DESIGN = {"wc": 20.0, "wo": 100.0, "b0": 8.892, "order": 1}
PID_PAPER = {"kp": 1.15, "ki": 15.16, "kd": 0.01, "n": 100.0}
DIST_T, DIST = 1.5, 0.1


def fmt(v, nd=3):
    return "   n/a" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:7.{nd}f}"


def row(name, m=None, d=None, paper=None):
    """One table line: ours (m, d) or the paper's dict."""
    if paper is not None:
        cells = [paper.get(k) for k in ("r1090", "r090", "s2", "s5", "os", "sse", "dpk", "drec")]
    else:
        cells = [
            m.rise_10_90_s,
            m.rise_0_90_s,
            m.settling_2pct_s,
            m.settling_5pct_s,
            m.overshoot_pct,
            m.steady_state_error_pct,
            d.peak_deviation_pct if d else None,
            d.recovery_2pct_s if d else None,
        ]
    print(f"  {name:<38}" + " ".join(fmt(c) for c in cells))


HEADER = (
    f"  {'':<38}{'r10-90':>7} {'r0-90':>7} {'ts2%':>7} {'ts5%':>7} {'os%':>7} {'sse%':>7}"
    f" {'dpk%':>7} {'drec':>7}"
)


def seed001_run(ctrl, dt, duration=3.0, dist=True):
    plant = seed001_motor(dt)
    f = (lambda t: DIST if t >= DIST_T - 1e-12 else 0.0) if dist else None
    return closed_loop(ctrl, plant, 1.0, duration, disturbance=f)


def split_metrics(tr, dist=True):
    n = next(k for k, t in enumerate(tr.t) if t >= DIST_T - 1e-12)
    m = step_metrics(tr.t[:n], tr.y[:n], 0.0, 1.0)
    d = disturbance_metrics(tr.t, tr.y, 1.0, DIST_T, 1.0) if dist else None
    return m, d


def pid_reference():
    kp, ki, kd, n = PID_PAPER.values()
    cn = np.polyadd(
        np.polyadd(kp * np.array([1, n, 0]), ki * np.array([0, 1, n])), kd * n * np.array([1, 0, 0])
    )
    num = np.polymul(cn, SEED001_NUM)
    den = np.polyadd(np.polymul([1, n, 0], SEED001_DEN), num)
    t = np.arange(0.0, DIST_T, 1e-5)
    _, y = scipy.signal.step((num, den), T=t)
    return step_metrics(list(t), list(y), 0.0, 1.0)


def seed001(plots):
    print("\n== Seed 001: metering motor G(s) = (8.892 s + 0.04603)/(s^2 + 6.699 s + 0.03441) ==")
    print(
        "   unit step at 0 s; 0.1 input step disturbance at 1.5 s (dpk: peak deviation, % of step)"
    )
    print(HEADER)
    row(
        "paper Table 2, PID (rise def. unstated)",
        paper={"r090": 0.140, "s2": 0.476, "os": 10.33, "sse": 0.184},
    )
    ref = pid_reference()
    row("scipy continuous reference, PID", ref)
    res = {}
    tr_pid = seed001_run(PID(**PID_PAPER), 1e-4)
    m, d = split_metrics(tr_pid)
    row("ours PID, dt 0.1 ms (continuous)", m, d)
    res["seed001_pid"] = (m, d)
    tr_pid2 = seed001_run(PID(**PID_PAPER), 2e-3)
    m2, d2 = split_metrics(tr_pid2)
    row("ours PID, 2 ms digital", m2, d2)
    row("paper Table 2, LADRC", paper={"r090": 0.185, "s2": 0.290, "os": 0.85, "sse": 0.024})
    tr_p = seed001_run(LADRC(150.0, 400.0, 6000.0, order=2), 1e-4)
    row("LADRC as printed (o2 150/400/6000) 0.1ms", *split_metrics(tr_p))
    tr_p2 = seed001_run(LADRC(150.0, 400.0, 6000.0, order=2), 2e-3)
    row("  same, 2 ms, discrete ESO", *split_metrics(tr_p2))
    tr_e = seed001_run(LADRC(150.0, 400.0, 6000.0, order=2, observer="euler"), 2e-3, 0.5, False)
    blown = next((t for t, y in zip(tr_e.t, tr_e.y, strict=True) if not abs(y) < 1e3), None)
    print(f"  {'  same, 2 ms, Euler ESO':<38} UNSTABLE: |y| > 1e3 at t = {blown:.3f} s")
    tr_ptd = seed001_run(LADRC(150.0, 400.0, 6000.0, order=2, td_r=20.0), 2e-3)
    row("  printed + tracking diff. r=20, 2 ms", *split_metrics(tr_ptd))
    tr_l = seed001_run(LADRC(**LADRC_DESIGN), 2e-3)
    ml, dl = split_metrics(tr_l)
    row("FieldRx LADRC o1 wc20 wo100 b0 8.892 2ms", ml, dl)
    res["seed001_ladrc"] = (ml, dl)
    tr_lc = seed001_run(LADRC(**LADRC_DESIGN), 1e-4)
    row("  same, 0.1 ms", *split_metrics(tr_lc))
    print(f"  peak command on the step: PID {max(tr_pid2.u):.2f}, FieldRx LADRC {max(tr_l.u):.2f}")
    gain = 100 * (1 - dl.peak_deviation_pct / d2.peak_deviation_pct)
    print(
        f"  disturbance peak: LADRC {dl.peak_deviation_pct:.2f} % vs PID"
        f" {d2.peak_deviation_pct:.2f} % at 2 ms ({gain:.0f} % smaller;"
        " the paper claims 39 % better disturbance rejection)"
    )
    plots.append(
        (
            "seed001_step.png",
            "Seed 001 motor: unit step, 0.1 input disturbance at 1.5 s",
            [
                ("PID paper gains", tr_pid2),
                ("LADRC as printed (o2)", tr_p2),
                ("LADRC printed + TD", tr_ptd),
                ("FieldRx LADRC o1", tr_l),
            ],
        )
    )
    return res


def seed000_run(rule, step, tc):
    """Step 8 -> 8 + step, then 4 s more with a -0.3 V load disturbance (-3.1 r/min static)."""
    plant = seed000_shaft(1e-3, time_constant=tc)
    plant.reset(8.0)
    c = IncrementalPID(rule=rule, out_min=plant.u_min, out_max=plant.u_max)
    c.warm_start(plant.equilibrium_input(8.0))
    kw = {"ctrl_period_s": SEED000_LOOP_PERIOD_S, "feedback_scale": SEED000_FEEDBACK_SCALE}
    tr = closed_loop(c, plant, 8.0 + step, 6.0, **kw)
    dist = closed_loop(c, plant, 8.0 + step, 4.0, disturbance=lambda t: -0.3, **kw)
    return (
        tr,
        step_metrics(tr.t, tr.y, 8.0, 8.0 + step),
        disturbance_metrics(dist.t, dist.y, 8.0 + step, 0.0, step),
    )


def seed000(plots):
    print("\n== Seed 000: shaft speed chain, incremental PID vs integral separation (eq. 11-12) ==")
    print(
        "   8 r/min -> 8 + step; 0.1 s loop on encoder volts; 0-5 V driver limit; dead time 10 ms"
    )
    print("   then a -0.3 V load step (dpk: peak deviation, % of the step; drec: 2 % recovery)")
    print(HEADER)
    paper = {
        15.0: {"isp": (1.5, 7.0), "none": (1.9, 8.6)},
        25.0: {"isp": (1.4, 9.0), "none": (2.4, 17.8)},
    }
    out = {}
    curves = []
    for step in (15.0, 25.0):
        key = f"step{int(step)}"
        out[key] = {}
        for tc in ("printed", "derived"):
            for rule, label in (
                ("none", "plain incremental PID"),
                ("relative_change", "ISP eq.12"),
                ("error_band", "ISP |e|<=0.7"),
            ):
                tr, m, d = seed000_run(rule, step, tc)
                row(f"+{step:.0f} {tc[:5]} {label}", m, d)
                if tc == "printed" and rule != "error_band":
                    curves.append((f"+{step:.0f} {label}", tr))
                suffix = "" if tc == "printed" else "_derived"
                if rule == "none":
                    out[key]["pid_overshoot_pct" + suffix] = m.overshoot_pct
                    out[key]["pid_settling_5pct_s" + suffix] = m.settling_5pct_s
                elif rule == "relative_change":
                    out[key]["isp_overshoot_pct" + suffix] = m.overshoot_pct
                    out[key]["isp_settling_5pct_s" + suffix] = m.settling_5pct_s
        (pt_i, po_i), (pt_p, po_p) = paper[step]["isp"], paper[step]["none"]
        print(
            f"  paper +{step:.0f}: ISP {pt_i} s / {po_i} %, PID {pt_p} s / {po_p} %"
            " (transition time / overshoot)"
        )
    print("  error_band with eps 0.7 V never engages: the P-only offset stays above the band,")
    print(
        "  so the integral never switches on (large steady-state error). eq. 12's relative rule"
        " works, but it also cuts the integral when a load step hits (larger dpk above). The"
        " 0-5 V limit does not bind on these steps at a 0.1 s loop, so unlike the"
        " paper (8.6 -> 17.8 %) our overshoot does not grow with the step size."
    )
    plots.append(("seed000_steps.png", "Seed 000 shaft speed (printed time constant)", curves))
    return out


def depth_run(ctrl, duration=5.0, amp=1.0):
    plant = seed002_depth(1e-3)
    tr = closed_loop(ctrl, plant, amp, duration)
    return tr, step_metrics(tr.t, tr.y, 0.0, amp)


def depth_disturbance(ctrl):
    """Unit step, then a 0.005 input step (a soil load worth 2.3 mm if uncorrected) for 5 s."""
    plant = seed002_depth(1e-3)
    closed_loop(ctrl, plant, 1.0, 5.0)
    tr = closed_loop(ctrl, plant, 1.0, 5.0, disturbance=lambda t: 0.005)
    return disturbance_metrics(tr.t, tr.y, 1.0, 0.0, 1.0)


def lim():
    return {"out_min": -DEPTH_U_LIMIT, "out_max": DEPTH_U_LIMIT}


def tune_fixed():
    best = None
    for kp, ki, kd in itertools.product([2, 4, 6, 8, 12], [0.05, 0.1, 0.2, 0.5], [1, 2, 3, 4]):
        _, m = depth_run(PID(kp, ki, kd, n=None, **lim()))
        if m.overshoot_pct <= 2.0 and not math.isnan(m.settling_2pct_s):
            if best is None or m.iae < best[0]:
                best = (m.iae, kp, ki, kd)
    print(f"  fixed-PID grid: best Kp {best[1]}, Ki {best[2]}, Kd {best[3]} (IAE {best[0]:.4f})")


def tune_fuzzy(fixed):
    best = None
    grid = itertools.product(
        [0.03, 0.3, 1, 3, 6, 10],
        [0.01, 0.12, 1, 3, 10],
        [0.3, 1, 3, 6],
        [0.05, 0.1, 0.2, 0.5],
        [0.02, 0.005],
    )
    for ke, kec, kdp, kdd, kdi in grid:
        f = {"k_e": ke, "k_ec": kec, "k_dkp": kdp, "k_dkd": kdd, "k_dki": kdi}
        _, m = depth_run(FuzzyPID(**DEPTH_PID_GAINS, **f, **lim()))
        ok = (
            m.overshoot_pct <= fixed.overshoot_pct
            and m.settling_2pct_s <= fixed.settling_2pct_s
            and m.iae <= fixed.iae
        )
        if ok and (best is None or m.iae < best[0]):
            best = (m.iae, f)
    print(f"  fuzzy factor grid (960 runs): best {best[1]} (IAE {best[0]:.4f})")


def seed002(plots, tune):
    print("\n== Seed 002: sowing depth, corrected loop 2.6091/(0.592 s^2 + s + 0.005672), 1 ms ==")
    print("   unit step (the paper's square-wave amplitude); cylinder limit |u| <= 19.2 (50 mm/s)")
    print(f"{HEADER} {'IAE':>7}")
    print("   (dpk/drec: 0.005 input step after settling, worth 2.3 mm uncorrected; % of 1 mm)")
    ctrls = {
        "fixed PID Kp12 Ki0.05 Kd3": lambda: PID(**DEPTH_PID_GAINS, n=None, **lim()),
        "fuzzy PID, Table 2 factors": lambda: FuzzyPID(
            **DEPTH_PID_GAINS, **TABLE2_FACTORS, **lim()
        ),
        "fuzzy PID, tuned factors": lambda: FuzzyPID(
            **DEPTH_PID_GAINS, **STEP_TUNED_FUZZY_FACTORS, **lim()
        ),
    }
    runs = {}
    for name, make in ctrls.items():
        tr, m = depth_run(make())
        d = depth_disturbance(make())
        runs[name] = (tr, m, d)
        cells = [
            m.rise_10_90_s,
            m.rise_0_90_s,
            m.settling_2pct_s,
            m.settling_5pct_s,
            m.overshoot_pct,
            m.steady_state_error_pct,
            d.peak_deviation_pct,
            d.recovery_2pct_s,
            m.iae,
        ]
        print(f"  {name:<38}" + " ".join(fmt(c) for c in cells))
    print("  10 mm step (saturating the cylinder; not tuned for), os % / ts2 s / IAE:")
    for name, make in ctrls.items():
        _, m10 = depth_run(make(), amp=10.0)
        print(
            f"    {name:<36} {m10.overshoot_pct:6.2f} % / {m10.settling_2pct_s:5.3f} s /"
            f" {m10.iae:6.3f}"
        )
    print("  (the factor tuning is for the unit step: on 10 mm the tuned fuzzy PID settles faster")
    print("   with less IAE but overshoots more than the fixed PID; drec 0 = never left the band)")
    (tr_f, fixed, _), (tr_t, table2, _), (tr_z, fuzzy, _) = runs.values()
    print(f"  tuned factors: {STEP_TUNED_FUZZY_FACTORS}; Table 2: {TABLE2_FACTORS}")
    print("  paper: no numbers, only 'smaller overshoot and shorter settling' (Fig. 13).")
    win = (
        "fuzzy"
        if (
            fuzzy.overshoot_pct <= fixed.overshoot_pct
            and fuzzy.iae <= fixed.iae
            and fuzzy.settling_2pct_s <= fixed.settling_2pct_s
        )
        else "mixed"
    )
    print(f"  verdict: tuned fuzzy vs fixed -> {win}; with Table 2 factors the fuzzy PID settles")
    print("  faster with less IAE but overshoots more than the fixed PID.")
    if tune:
        tune_fixed()
        tune_fuzzy(fixed)
    plots.append(
        (
            "seed002_depth.png",
            "Seed 002 depth loop, unit step",
            [("fixed PID", tr_f), ("fuzzy, Table 2", tr_t), ("fuzzy, tuned", tr_z)],
        )
    )
    return {
        "fuzzy_overshoot_pct": fuzzy.overshoot_pct,
        "fixed_overshoot_pct": fixed.overshoot_pct,
        "fuzzy_iae": fuzzy.iae,
        "fixed_iae": fixed.iae,
        "fuzzy_settling_2pct_s": fuzzy.settling_2pct_s,
        "fixed_settling_2pct_s": fixed.settling_2pct_s,
        "table2_overshoot_pct": table2.overshoot_pct,
        "table2_iae": table2.iae,
    }


def kalman(plots):
    print("\n== Seed 001 eq. 14-15: Kalman speed filter at 1.5 m/s ==")
    print("   simulated: 120 m at 1.5 m/s, 10 Hz fixes, white speed noise sigma 2.5 %")
    bands = []
    for seed in range(20):
        z = 1.5 * (1 + np.random.default_rng(seed).normal(0.0, 0.025, 800))
        kf = KalmanSpeedFilter()
        f = np.array([kf.update(float(v)) for v in z])
        raw = (z / 1.5 - 1) * 100
        fil = (f / 1.5 - 1) * 100
        bands.append((raw.min(), raw.max(), fil.min(), fil.max(), fil[10:].min(), fil[10:].max()))
        if seed == 0:
            z0, f0 = z, f
    b = np.array(bands)
    print("  paper:  raw -8.89 .. 7.57 %  -> filtered -3.80 .. 3.21 %")
    print(
        f"  ours (seed 0): raw {b[0, 0]:.2f} .. {b[0, 1]:.2f} % -> filtered {b[0, 2]:.2f} .. "
        f"{b[0, 3]:.2f} % (all fixes), {b[0, 4]:.2f} .. {b[0, 5]:.2f} % after 1 s warm-up"
    )
    print(
        f"  20 noise seeds, worst after warm-up: {b[:, 4].min():.2f} .. {b[:, 5].max():.2f} %;"
        f" worst including the first fixes: {b[:, 2].min():.2f} .. {b[:, 3].max():.2f} %"
    )
    print("  (initialised from the first fix, so the first estimate carries that fix's raw error)")
    plots.append(
        ("kalman_speed.png", "Kalman speed filter, 1.5 m/s", [("raw", z0), ("filtered", f0)])
    )
    raw_band = max(abs(b[0, 0]), abs(b[0, 1]))
    filt_band = max(abs(b[0, 4]), abs(b[0, 5]))
    return {
        "raw": raw_band,
        "filtered": filt_band,
        "filtered_all_fixes": max(abs(b[0, 2]), abs(b[0, 3])),
        "filtered_worst_20_seeds": max(abs(b[:, 4].min()), abs(b[:, 5].max())),
    }


def step_cost():
    print("\n== Cost of one step() in CPython (median of 7 x 20000 calls) ==")

    def baseline(r, y, dt):
        return r - y

    ctrls = {
        "baseline_python_call": baseline,
        "pid": PID(**PID_PAPER, out_min=0.0, out_max=100.0).step,
        "incremental_pid": IncrementalPID(out_min=0.0, out_max=5.0).step,
        "ladrc_o1": LADRC(**LADRC_DESIGN, out_min=0.0, out_max=100.0).step,
        "ladrc_o2": LADRC(150.0, 400.0, 6000.0, order=2).step,
        "ladrc_o1_td": LADRC(**LADRC_DESIGN, td_r=40.0).step,
        "fuzzy_pid": FuzzyPID(**DEPTH_PID_GAINS, **STEP_TUNED_FUZZY_FACTORS, **lim()).step,
    }
    rng = np.random.default_rng(1)
    ys = [float(v) for v in rng.uniform(0.0, 2.0, 20000)]
    out = {}
    for name, fn in ctrls.items():
        runs = []
        for _ in range(7):
            t0 = time.perf_counter()
            for y in ys:
                fn(1.0, y, 0.002)
            runs.append((time.perf_counter() - t0) / len(ys) * 1e6)
        out[name] = float(np.median(runs))
    base = out["baseline_python_call"]
    for name, us in out.items():
        print(f"  {name:<22} {us:6.2f} us  ({us / base:5.1f} x a trivial call)")
    worst = max(v for k, v in out.items() if k != "baseline_python_call")
    print(
        f"  worst controller {worst:.2f} us: {'under' if worst < 20 else 'OVER'} the 20 us budget"
    )
    return out


def save_plots(plots):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(OUT, exist_ok=True)
    for fname, title, curves in plots:
        fig, ax = plt.subplots(figsize=(8, 4.5))
        for label, tr in curves:
            if hasattr(tr, "t"):
                ax.plot(tr.t, tr.y, label=label, lw=1.2)
            else:
                ax.plot(np.arange(len(tr)) / 10.0, tr, label=label, lw=1.0)
        ax.set_title(title)
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(os.path.join(OUT, fname), dpi=110)
        plt.close(fig)
    print(f"\nplots: {', '.join(os.path.join('bench/out', p[0]) for p in plots)}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tune", action="store_true", help="re-run the seed 002 grid searches")
    args = ap.parse_args()
    plots = []
    s1 = seed001(plots)
    s0 = seed000(plots)
    s2 = seed002(plots, args.tune)
    kb = kalman(plots)
    cost = step_cost()
    save_plots(plots)

    def pack(md):
        m, d = md
        return {
            "rise_10_90_s": round(m.rise_10_90_s, 4),
            "rise_0_90_s": round(m.rise_0_90_s, 4),
            "settling_2pct_s": round(m.settling_2pct_s, 4),
            "settling_5pct_s": round(m.settling_5pct_s, 4),
            "overshoot_pct": round(m.overshoot_pct, 3),
            "disturbance_peak_pct": round(d.peak_deviation_pct, 3),
        }

    summary = {
        "seed001_pid": pack(s1["seed001_pid"]),
        "seed001_ladrc": pack(s1["seed001_ladrc"]),
        "seed000": {k: {kk: round(vv, 3) for kk, vv in v.items()} for k, v in s0.items()},
        "seed002": {k: round(v, 4) for k, v in s2.items()},
        "kalman_band_pct": {k: round(float(v), 2) for k, v in kb.items()},
        "step_us": {k: round(v, 2) for k, v in cost.items()},
        "step_us_ratio_to_baseline": {
            k: round(v / cost["baseline_python_call"], 1)
            for k, v in cost.items()
            if k != "baseline_python_call"
        },
    }
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
