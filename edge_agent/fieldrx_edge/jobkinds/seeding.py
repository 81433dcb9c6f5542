"""Seed 002 as a job: depth sensor (mV, eq. 13) -> fuzzy PID -> press-roller cylinder.

``DepthJobLoop`` is the agent's per-sample decision (sensor line -> guarded depth);
``simulate_seeding`` drives the loop over the job's planned field at the paper's three
test speeds (2 / 4 / 6 km/h, bands 1-3 / 3-5 / 5-7 km/h, Table 3).

Plant: ``plants.seed002_depth`` (corrected eq. 9, 2.6091 / (0.592 s^2 + s + 0.005672)) with
the cylinder's 50 mm/s limit; its output is the depth change the roller adjustment makes,
reported as ``actuator_mm``. Controller at 1 ms (sec. 3.3): adaptive fuzzy PID with
``fieldrx_edge.depth``'s gains and factors (Table 2's universes), or the fixed PID.

Disturbance model (the depth the opener would give without control, along the path), mm:

* Soil compaction: bulk density varies over metres to tens of metres; the opener's
  sinkage varies with it. AR(1) in distance with 8 m correlation and 4 mm sigma, so an
  uncontrolled drill would leave ~1 in 50 seeds outside the +-10 mm band (GB/T 20865).
* Surface roughness after rotary tillage (clods, 1-4 cm): 0.4 m correlation, 1.2 mm sigma
  at 3-5 km/h; at 1-3 km/h 1.4x (the paper, sec. 4: slow driving throws the soil worse, its
  SD and CV are highest there) and at 5-7 km/h 1.2x. The roughness the roller cannot follow
  is what remains after control.
* Sensor: 5 mV ADC noise (1 sigma) on the tilt sensor, 0.33 mm through eq. 13's slope.

The papers' SD 0.18 mm with CV 2.93 % and 93 % qualified cannot all hold (SCIENCE.md); ours
are computed from the same records as the server's report.

Results (bench/seeds.py, 3 drives): fuzzy PID qualified 99.98 / 100 / 100 % (goal >= 95 %,
paper 92 / 93 / 91 %), SD 1.23 / 1.23 / 1.73 mm, CV 4.1 / 4.1 / 5.7 % (paper 2.93 % best);
fixed PID SD 1.21 / 1.22 / 1.72 mm. **Goal not met:** the fuzzy PID is not at least as good
as the fixed PID in every band; both are within 1.5 % of each other, because what remains is
the sub-metre roughness the 50 mm/s cylinder through a 0.592 s mechanism cannot follow and
the sensor noise, which no retuning of the gains removes (a grid of fuzzy factors, k_e 0.03-1,
k_ec 0.1-1, k_dkp 0.3-6, k_dkd 0-0.5, moved the SD by under 2 %). Our CV is above the
paper's 2.93 % for the same reason; the paper's SD of 0.18 mm is inconsistent with its own CV.

Why the fuzzy PID cannot beat the fixed PID here (checked again for issue 13, seeds 0-2, SD mm
in the 1-3 / 3-5 / 5-7 km/h bands; qualified 99.9-100 % for every controller):

* The paper prints no fixed-PID gains: K'p, K'i, K'd of eq. 10 are "preset values" and it
  compares no fixed PID in the field. Our fixed PID (``DEPTH_PID_GAINS``) is the grid-search
  optimum of the corrected loop and is also the fuzzy PID's K', so the fuzzy PID can only
  move the gains away from an optimum. On this disturbance the optimum is flat: fixed PID Kp
  6 / 12 / 24 / 48 gives 1.28 / 1.25 / 1.29 / 1.43 mm at 1-3 km/h (seed 0), and the fuzzy
  correction is at most dKp 0.9 (Table 2), 7.5 % of Kp.
* The loop is limited by the cylinder, not the gains: 50 mm/s over the loop gain 2.6091 caps
  the controller output at 19.2, reached by Kp 12 at a 1.6 mm error, and what remains
  (sub-metre roughness through the 0.592 s mechanism, 0.33 mm sensor noise) is beyond any
  gain schedule.
* Table 2's factors put every error the disturbance makes inside E's ZE set (k_e 0.03: a
  4 mm error is E 0.12 of the [-6, 6] universe), so the rule tables act almost only through
  Ec, the noisiest signal in the loop (largely the filtered derivative of sensor noise and
  roughness): the gains wander with it, which costs a little variance.
* Measured (bench/seeds.py, mean of seeds 0-2): fixed PID 1.210 / 1.215 / 1.717; fuzzy PID
  with the job's default factors (``DEPTH_FUZZY_FACTORS``, tuned: k_ec 1.0, k_dkp 3.0,
  k_dkd 0.05) 1.225 / 1.225 / 1.728; fuzzy PID with Table 2's factors exactly
  (``TABLE2_FACTORS``) 1.217 / 1.224 / 1.738. Fuzzy is 0.1-1.3 % worse in every band with
  either set of factors (per seed up to 2 %): the goal "fuzzy at least as good as fixed in
  every band" is not met honestly, and neither weakening the baseline nor a disturbance the
  paper does not describe (large steps, where the fuzzy PID's step-response advantage of
  sec. 4.3 would show) is used to meet it. Qualified >= 95 % is met by both.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fieldrx_edge.control import PID, FuzzyPID
from fieldrx_edge.depth import DEPTH_FUZZY_FACTORS, DEPTH_PID_GAINS, DepthSensorCalibration
from fieldrx_edge.jobkinds.common import Feed, cells_worked, drive, record
from fieldrx_edge.jobkinds.figures import depth_table, qualified_alert
from fieldrx_edge.jobkinds.sensors import SensorError, SensorGuard, parse_depth_mv
from fieldrx_edge.jobkinds.topdress import figure_rows
from fieldrx_edge.plants import seed002_depth
from fieldrx_edge.plants.seeds import seed002_open_loop_gain
from fieldrx_edge.protocol import JobPackage

COMPACTION_SD_MM = 4.0
COMPACTION_CORR_M = 8.0
ROUGH_SD_MM = 1.2
ROUGH_CORR_M = 0.4
ADC_NOISE_MV = 5.0
TEST_SPEEDS_KMH = (2.0, 4.0, 6.0)
SENSOR_EVERY = 10  # loop periods per sensor sample (100 Hz sensor, 1 kHz loop)
# derivative filter (rad/s) of both controllers: an unfiltered backward difference at 1 ms
# turns 0.33 mm of sensor noise into 330 mm/s of "error rate" and chatters the cylinder
DERIVATIVE_FILTER = 20.0


def rough_factor(v_kmh: float) -> float:
    return 1.4 if v_kmh < 3.0 else 1.0 if v_kmh < 5.0 else 1.2


def build_depth_controller(ctl: dict[str, Any], actuator_mm_s: float) -> Any:
    """Fuzzy PID (default) or fixed PID, output limited by the cylinder speed."""
    lim = actuator_mm_s / seed002_open_loop_gain()
    p = dict(ctl.get("params") or {})
    if ctl["name"] == "pid":
        return PID(**{**DEPTH_PID_GAINS, "n": DERIVATIVE_FILTER, **p}, out_min=-lim, out_max=lim)
    base = {**DEPTH_PID_GAINS, **DEPTH_FUZZY_FACTORS, "n": DERIVATIVE_FILTER, **p}
    return FuzzyPID(**base, out_min=-lim, out_max=lim)


class DepthJobLoop:
    """Sensor line (or mV value) -> guarded measured depth; None when the sensor is lost."""

    def __init__(self, job: JobPackage) -> None:
        s = job.kind_settings
        c = s["sensor_calibration"]
        self.settings = s
        self.cal = DepthSensorCalibration(c["slope_mm_per_mv"], c["intercept_mm"], (-1e9, 1e9))
        self.min_mv = float(c["signal_min_mv"])
        self.max_mv = float(c["signal_max_mv"])
        self.guard = SensorGuard(float(s["sensor_hold_s"]))
        self.target_mm = float(s["target_depth_mm"])

    def on_line(self, t: float, line: str) -> float:
        """Take one sensor line; returns its time (the line's own, else ``t``)."""
        try:
            tl, mv = parse_depth_mv(line, self.min_mv, self.max_mv)
        except SensorError as exc:
            self.guard.bad(exc.reason)
            return t
        t = tl if tl is not None else t
        self.guard.good(t, self.cal.depth_mm(mv))
        return t

    def on_mv(self, t: float, mv: float | None) -> None:
        if mv is None:
            self.guard.bad("silent")
        elif not self.min_mv <= mv <= self.max_mv:
            self.guard.bad("range")
        else:
            self.guard.good(t, self.cal.depth_mm(mv))

    def depth(self, t: float) -> tuple[float | None, list[str]]:
        return self.guard.value(t)


def _ar1(n: int, step_m: float, corr_m: float, sd: float, rng: np.random.Generator) -> np.ndarray:
    a = float(np.exp(-step_m / corr_m))
    e = rng.normal(0.0, sd * np.sqrt(1 - a * a), n)
    out = np.empty(n)
    x = float(rng.normal(0.0, sd))
    for i in range(n):
        x = a * x + e[i]
        out[i] = x
    return out


def simulate_seeding(
    job: JobPackage,
    seed: int = 0,
    sink: Any | None = None,
    controller: dict[str, Any] | None = None,
    fault_at_s: tuple[float, float] | None = None,
    hz: float = 10.0,
    realtime: float = 0.0,
) -> dict[str, Any]:
    """Drive the job; records (10 Hz) go to ``sink``. Returns the simulator's own Table 3."""
    s = job.kind_settings
    ctl_cfg = controller or s["controller"]
    d = drive(job, list(TEST_SPEEDS_KMH), hz, seed)
    loop = DepthJobLoop(job)
    ctrl = build_depth_controller(ctl_cfg, float(s["actuator_speed_mm_s"]))
    period = float(ctl_cfg.get("period_s") or 0.001)
    plant = seed002_depth(period)
    rng = np.random.default_rng(seed + 11)
    # disturbance on a 0.05 m distance grid
    dist = np.concatenate([[0.0], np.cumsum(d.v_true[1:] / hz)])
    step = 0.05
    n_grid = int(dist[-1] / step) + 2
    comp = _ar1(n_grid, step, COMPACTION_CORR_M, COMPACTION_SD_MM, rng)
    rough = _ar1(n_grid, step, ROUGH_CORR_M, ROUGH_SD_MM, rng)
    target = loop.target_mm
    sub = int(round(1.0 / hz / period))
    y = 0.0
    u = 0.0
    noise = 0.0
    recs: list[dict[str, Any]] = []
    feed = Feed(sink, realtime, d)
    for i in range(len(d.t)):
        t = float(d.t[i])
        working = bool(d.down[i])
        v_kmh = float(d.v_true[i]) * 3.6
        # sensor sample at the record instant
        g = min(int(dist[i] / step), n_grid - 1)
        true_depth = target + comp[g] + rough_factor(v_kmh) * rough[g] + y
        mv: float | None = loop.cal.signal_mv(true_depth) + float(rng.normal(0.0, ADC_NOISE_MV))
        if fault_at_s is not None and fault_at_s[0] <= t < fault_at_s[1]:
            mv = None
        loop.on_mv(t, mv)
        meas, alarms = loop.depth(t)
        gains = getattr(ctrl, "gains", (ctrl.kp, ctrl.ki, ctrl.kd))
        rec = record(
            job,
            d,
            i,
            depth_mm=meas if working else None,
            actuator_mm=y,
            duty=u,
            gain_kp=float(gains[0]),
            gain_ki=float(gains[1]),
            gain_kd=float(gains[2]),
            alarms=sorted(set(alarms)) if working else [],
        )
        recs.append(rec)
        feed.put(rec, t)
        # the loop between samples: the sensor is read every period (1 ms); the path moves on
        v = float(d.v_true[i])
        for k in range(sub):
            gk = min(int((dist[i] + v * k * period) / step), n_grid - 1)
            dep = target + comp[gk] + rough_factor(v_kmh) * rough[gk] + y
            if meas is None:
                u = 0.0  # sensor lost: hold the roller where it is (the plant integrates u)
            elif k == 0 or fault_at_s is not None and fault_at_s[0] <= t < fault_at_s[1]:
                u = ctrl.step(target, meas, period)  # held value while the sensor is faulty
            else:
                if k % SENSOR_EVERY == 0:  # a new sensor sample every 10 ms, held in between
                    noise = float(rng.normal(0.0, ADC_NOISE_MV * abs(loop.cal.slope_mm_per_mv)))
                u = ctrl.step(target, dep + noise, period)
            y = plant.step(u)
    feed.close()
    rows = figure_rows(recs)
    table = depth_table(rows, s["speed_bands_kmh"], target)
    alert = qualified_alert(rows, target, s["alert_window_m"], s["alert_min_qualified_pct"])
    return {
        "kind": "seeding_depth",
        "controller": ctl_cfg["name"],
        "records": len(recs),
        "cells_worked": cells_worked(recs),
        "depth_table": table,
        "qualified_alert": alert,
        "sensor_errors": dict(loop.guard.errors),
        "duration_s": float(d.t[-1]),
    }
