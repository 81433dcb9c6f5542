"""Seed 000 and seed 002 as jobs: the papers' field figures beside ours, on the same
disturbance, for the paper's controller and the alternative.

Run: .venv/bin/python bench/seeds.py [--seeds 3]

Both kinds are driven by the same simulators as `fieldrx-edge simulate` (fieldrx_edge.jobkinds:
disturbance models and their magnitudes are in topdress.py / seeding.py docstrings) over a
rectangular field, several random seeds; every controller sees the identical drive, NDVI
field, load and soil. Tables are fieldrx_edge.jobkinds.figures, the definition the server's
report uses. Ends with one JSON line.

Seed 000 (Table 3): mean |monitored - theoretical| / theoretical shaft speed at the four test
speeds, constant-speed stretches (2 s after the implement goes down); paper 2.0 / 3.6 / 3.8 /
4.0 %, mean 3.35 %. Also the raw 4-sensor NDVI sigma for the two layouts (paper Table 1:
distributed 0.030, over-row 0.065).

Seed 002 (Table 3): mean depth, qualified share (GB/T 20865, 20-40 mm), SD and CV in the
1-3 / 3-5 / 5-7 km/h bands; paper best 93 % and CV 2.93 % at 3-5 km/h (its SD 0.18 mm with
CV 2.93 % at a 30 mm mean is inconsistent: 2.93 % of 30.13 mm is 0.88 mm, docs/science.md). Ours on
the dug-out (true) depth, as GB/T 20865 measures, beside the telemetry (sensor) figure the
server reports; the fuzzy PID (Table 2) and the fixed PID share K' and see the same drive.
Then the SD split into its causes (``decompose``: 4 more runs per drive; --no-decomposition
skips it). Why the fuzzy PID does not beat the fixed PID: fieldrx_edge.jobkinds.seeding.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from typing import Any

import numpy as np
from fieldrx_edge.depth import DEPTH_PID_GAINS
from fieldrx_edge.jobkinds.seeding import DepthDisturbance, simulate_seeding
from fieldrx_edge.jobkinds.settings import validate_settings
from fieldrx_edge.jobkinds.topdress import simulate_topdress
from fieldrx_edge.ndvi import SEED000_TABLE
from fieldrx_edge.sim.fields import RectField, rect_job

PAPER000 = {
    "bands": [2.0, 3.6, 3.8, 4.0],
    "mean": 3.35,
    "sigma": {"distributed": 0.030, "over_row": 0.065},
}
PAPER002 = {
    "mean_mm": [31.49, 30.13, 31.75],
    "qualified_pct": [92.0, 93.0, 91.0],
    "sd_mm": [0.26, 0.18, 0.21],
    "cv_pct": [3.51, 2.93, 3.26],
}


def job(
    kind: str, length: float, width: float, impl: float, settings: dict[str, Any] | None = None
) -> Any:
    j = rect_job(RectField(length_m=length, width_m=width, implement_width_m=impl))
    return dataclasses.replace(
        j,
        kind=kind,
        kind_settings=validate_settings(kind, settings or {}),
        calibration=SEED000_TABLE.to_dict(),
        checksum="",
    ).seal()


def seed000(seeds: list[int]) -> dict[str, Any]:
    j = job("ndvi_topdress", 100.0, 3.6 * 8, 3.6)
    ctls = {
        "ISP eq. 11-12 (paper)": None,
        "incremental PID (no separation)": validate_settings(
            "ndvi_topdress", {"controller": {"name": "incremental_pid"}}
        )["controller"],
        "LADRC order 1": validate_settings("ndvi_topdress", {"controller": {"name": "ladrc"}})[
            "controller"
        ],
    }
    out: dict[str, Any] = {}
    print("\n== Seed 000: theoretical vs monitored shaft speed, relative error % (Table 3) ==")
    print(f"   {len(seeds)} drives of {j.n_cells} cells; speeds 3.6 / 5.2 / 6.4 / 7.9 km/h")
    print(f"{'controller':34s} {'3.6':>6} {'5.2':>6} {'6.4':>6} {'7.9':>6} {'mean':>6}")
    print(
        f"{'paper (ISP, field test)':34s} "
        + " ".join(f"{v:6.2f}" for v in PAPER000["bands"])
        + f" {PAPER000['mean']:6.2f}"
    )
    for name, ctl in ctls.items():
        bands = []
        for sd in seeds:
            r = simulate_topdress(j, seed=sd, controller=ctl)
            bands.append([b["relative_error_pct"] for b in r["shaft_table"]["bands"]])
        b = np.mean(bands, axis=0)
        print(f"{name:34s} " + " ".join(f"{v:6.2f}" for v in b) + f" {b.mean():6.2f}")
        out[name] = {"bands": [round(float(v), 3) for v in b], "mean": round(float(b.mean()), 3)}
    sig = {}
    for lay in ("distributed", "over_row"):
        sig[lay] = float(
            np.mean([simulate_topdress(j, seed=sd, layout=lay)["ndvi_raw_sigma"] for sd in seeds])
        )
    print(
        f"raw 4-sensor NDVI sigma: distributed {sig['distributed']:.3f} (paper 0.030),"
        f" over-row {sig['over_row']:.3f} (paper 0.065)"
    )
    out["ndvi_sigma"] = {k: round(v, 4) for k, v in sig.items()}
    return out


BANDS002 = ("1-3", "3-5", "5-7")


def _band(tab: dict[str, Any], key: str) -> list[float]:
    return [float(b[key]) for b in tab["bands"]]


def _mean(runs: list[dict[str, Any]], table: str, key: str) -> np.ndarray:
    return np.mean([_band(r[table], key) for r in runs], axis=0)


def seed002(seeds: list[int], decomposition: bool = True) -> dict[str, Any]:
    j = job("seeding_depth", 60.0, 2.3 * 6, 2.3)
    ctls = {
        "fuzzy PID (paper, Table 2)": None,  # the job default: Table 2 factors, K' below
        "fixed PID (same K')": validate_settings("seeding_depth", {"controller": {"name": "pid"}})[
            "controller"
        ],
    }
    fuzzy_name, fixed_name = ctls
    runs = {
        n: [simulate_seeding(j, seed=sd, controller=c) for sd in seeds] for n, c in ctls.items()
    }
    out: dict[str, Any] = {}
    print("\n== Seed 002: sowing depth per speed band, target 30 mm (Table 3) ==")
    print(
        f"   {len(seeds)} drives; K' = {DEPTH_PID_GAINS} for both controllers, same soil and noise"
    )
    print("   dug out = true seed depth, what GB/T 20865 and the paper measure (sec. 4.4.2);")
    print("   telemetry = the sensor's depth (eq. 13, noise included), what the server reports")
    print(
        f"{'controller':27s} {'band':>4} {'mean mm':>8} {'qual %':>7} {'SD mm':>6} {'CV %':>6}"
        f" | {'telemetry SD':>12} {'CV %':>6}"
    )
    for i, band in enumerate(BANDS002):
        print(
            f"{'paper (dug out)':27s} {band:>4} {PAPER002['mean_mm'][i]:8.2f}"
            f" {PAPER002['qualified_pct'][i]:7.1f} {PAPER002['sd_mm'][i]:6.2f}"
            f" {PAPER002['cv_pct'][i]:6.2f} |"
        )
    for name, rs in runs.items():
        m = {k: _mean(rs, "true_depth_table", k) for k in ("mean_mm", "qualified_pct", "sd_mm")}
        cv = _mean(rs, "true_depth_table", "cv_pct")
        tsd = _mean(rs, "depth_table", "sd_mm")
        tcv = _mean(rs, "depth_table", "cv_pct")
        for i, band in enumerate(BANDS002):
            print(
                f"{name:27s} {band:>4} {m['mean_mm'][i]:8.2f} {m['qualified_pct'][i]:7.2f}"
                f" {m['sd_mm'][i]:6.3f} {cv[i]:6.2f} | {tsd[i]:12.3f} {tcv[i]:6.2f}"
            )
        g = {k: np.mean([r["gains"][k] for r in rs], axis=0) for k in ("kp", "ki", "kd")}
        out[name] = {
            "mean_mm": [round(float(v), 3) for v in m["mean_mm"]],
            "qualified_pct": [round(float(v), 2) for v in m["qualified_pct"]],
            "sd_mm": [round(float(v), 3) for v in m["sd_mm"]],
            "cv_pct": [round(float(v), 3) for v in cv],
            "telemetry_sd_mm": [round(float(v), 3) for v in tsd],
            "telemetry_cv_pct": [round(float(v), 3) for v in tcv],
            "gains_mean_sd": {k: [round(float(x), 4) for x in v] for k, v in g.items()},
        }
    print(
        "gains while working, mean +- SD: "
        + "; ".join(
            f"{n}: "
            + ", ".join(f"{k} {v[0]:.3f}+-{v[1]:.3f}" for k, v in out[n]["gains_mean_sd"].items())
            for n in runs
        )
    )
    # paired per drive: the same soil and noise for both controllers
    diff = np.array(
        [
            [
                100.0 * (a - b) / b
                for a, b in zip(
                    _band(f["true_depth_table"], "sd_mm"),
                    _band(p["true_depth_table"], "sd_mm"),
                    strict=True,
                )
            ]
            for f, p in zip(runs[fuzzy_name], runs[fixed_name], strict=True)
        ]
    )
    print(
        "fuzzy - fixed dug-out SD per drive, % of fixed (mean [min, max]): "
        + "; ".join(
            f"{b} {diff[:, i].mean():+.2f} [{diff[:, i].min():+.2f}, {diff[:, i].max():+.2f}]"
            for i, b in enumerate(BANDS002)
        )
    )
    better = [out[fuzzy_name]["sd_mm"][i] <= out[fixed_name]["sd_mm"][i] for i in range(3)]
    qual = [min(out[n]["qualified_pct"]) >= 95.0 for n in runs]
    print(
        f"fuzzy PID SD <= fixed PID SD per band: {better}; qualified >= 95 % in every band: {qual}"
    )
    kd = out[fuzzy_name]["gains_mean_sd"]["kd"][0]
    print(
        f"  why: Table 2's k_e keeps every error of this field inside E's ZE set, whose rules"
        f" lower Kd (here to {kd:.2f}, K'd {DEPTH_PID_GAINS['kd']:g}) and move Kp around zero:"
    )
    print(
        "  the fuzzy PID is a fixed PID with a lower Kd, which follows the soil worse (track"
        " column below); details: fieldrx_edge.jobkinds.seeding docstring"
    )
    out["fuzzy_at_least_as_good"] = better
    out["fuzzy_vs_fixed_sd_pct"] = [round(float(v), 3) for v in diff.mean(axis=0)]
    out["qualified_at_least_95"] = qual
    if decomposition:
        out["decomposition"] = decompose(seeds, ctls, runs)
    return out


def decompose(
    seeds: list[int], ctls: dict[str, Any], runs: dict[str, list[dict[str, Any]]]
) -> dict[str, Any]:
    """Split each band's SD, variance by variance, adding one cause at a time on the same drive:
    open loop (no control) -> loop tracking error with a 10x faster cylinder and no sensor
    noise -> + the 50 mm/s cylinder -> + sensor noise through the loop (dug-out depth) ->
    + sensor noise on the reading (telemetry depth)."""
    fast = job("seeding_depth", 60.0, 2.3 * 6, 2.3, {"actuator_speed_mm_s": 500.0})
    slow = job("seeding_depth", 60.0, 2.3 * 6, 2.3)
    quiet = DepthDisturbance(sensor_noise_mv=0.0)
    print("\nSD split per band, mm (mean of drives); each step adds one cause, in quadrature:")
    print(
        f"{'controller':27s} {'band':>4} {'open':>6} {'fast,0n':>7} {'50mm/s':>7} {'dug':>6}"
        f" {'telem':>6} | {'track':>6} {'cyl':>6} {'n loop':>6} {'n read':>6}"
    )
    out: dict[str, Any] = {}
    for name, ctl in ctls.items():
        a = [simulate_seeding(fast, seed=sd, controller=ctl, disturbance=quiet) for sd in seeds]
        b = [simulate_seeding(slow, seed=sd, controller=ctl, disturbance=quiet) for sd in seeds]
        cols = {
            "open_loop": _mean(runs[name], "open_loop_table", "sd_mm"),
            "fast_cylinder_no_noise": _mean(a, "true_depth_table", "sd_mm"),
            "cylinder_50_no_noise": _mean(b, "true_depth_table", "sd_mm"),
            "dug_out": _mean(runs[name], "true_depth_table", "sd_mm"),
            "telemetry": _mean(runs[name], "depth_table", "sd_mm"),
        }
        seq = list(cols.values())
        parts = {
            "tracking": seq[1],
            "cylinder_limit": np.sqrt(np.maximum(seq[2] ** 2 - seq[1] ** 2, 0.0)),
            "noise_through_loop": np.sqrt(np.maximum(seq[3] ** 2 - seq[2] ** 2, 0.0)),
            "noise_on_reading": np.sqrt(np.maximum(seq[4] ** 2 - seq[3] ** 2, 0.0)),
        }
        for i, band in enumerate(BANDS002):
            print(
                f"{name:27s} {band:>4} "
                + " ".join(f"{c[i]:{w}.3f}" for c, w in zip(seq, (6, 7, 7, 6, 6), strict=True))
                + " | "
                + " ".join(f"{p[i]:6.3f}" for p in parts.values())
            )
        out[name] = {k: [round(float(v), 3) for v in c] for k, c in {**cols, **parts}.items()}
    print("  open: no control; fast,0n: 500 mm/s cylinder, no sensor noise; 50mm/s: the paper's")
    print("  cylinder, no noise; dug: + noise (true depth); telem: + noise on the reading.")
    print("  track / cyl / n loop / n read: each cause's share, sqrt of its variance increment")
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument(
        "--no-decomposition", action="store_true", help="skip seed 002's SD split (4 runs/drive)"
    )
    a = ap.parse_args()
    seeds = list(range(a.seeds))
    t0 = time.perf_counter()
    s0 = seed000(seeds)
    s2 = seed002(seeds, not a.no_decomposition)
    print(json.dumps({"seed000": s0, "seed002": s2, "wall_s": round(time.perf_counter() - t0, 1)}))


if __name__ == "__main__":
    main()
