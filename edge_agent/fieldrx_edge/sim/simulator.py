"""A tractor driving a job: path, speed profile, GNSS noise, motor, fertilizer fall.

The simulated machine drives the job's cells in path order (straight swath
lines through the cells, Bezier turns between them) with a speed profile in
the requested range. At the GNSS rate it feeds noisy fixes to the agent's own
``runtime.Pipeline``; the named controller drives the seed 001 motor plant at
the motor rate. Fertilizer metered at time t lands at t + lag_s at the outlet
position of that moment (seed 001 sec. 2.3). What landed where is then
computed with numpy: per-cell mass against the theoretical mass (seed 001
eq. 17-18), the lag distance at every cell border with a rate step, and the
mass that fell outside the field.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from fieldrx_edge.locate import FieldBoundary
from fieldrx_edge.metering import calibration_from_dict
from fieldrx_edge.motor import build_controller, closed_loop_t50_s
from fieldrx_edge.protocol import ControllerSettings, JobPackage
from fieldrx_edge.runtime import Pipeline, RuntimeConfig, make_record
from fieldrx_edge.sim.fastplant import FastPlant2


@dataclass
class SimConfig:
    speed_min_kmh: float = 3.0
    speed_max_kmh: float = 9.0
    gnss_noise_m: float = 0.02  # position noise (1 sigma), RTK-like
    speed_noise_m_s: float = 0.064  # raw GNSS speed noise (1 sigma): +-8.5 % at 1.5 m/s is ~2 sigma
    course_noise_deg: float = 0.5
    gnss_hz: float = 10.0
    motor_hz: float = 100.0
    controller: str | None = None  # None: the job's controller
    lag_compensation: bool = True
    seed: int = 0
    accel_m_s2: float = 0.5
    speed_wobble: float = 0.05  # slow speed variation along a swath (fraction)
    run_in_m: float | None = None
    compare_runs: int = 20  # swath runs simulated without compensation for the comparison
    edge_stop: bool = True  # anticipate the coast-down at field edges (RuntimeConfig.stop_extra_s)
    border_min_step: float = 0.08  # rate steps smaller than this fraction are not lag borders


@dataclass
class SimPath:
    s: np.ndarray  # cumulative distance of the fine path grid
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray  # course, rad clockwise from north
    run_id: np.ndarray  # swath run index, -1 on turns
    cell_a: np.ndarray  # along-path interval of each cell
    cell_b: np.ndarray
    run_of_cell: np.ndarray
    run_speed: np.ndarray


@dataclass
class SimResult:
    cell_accuracy_pct: np.ndarray
    cell_m1_g: np.ndarray
    cell_m2_g: np.ndarray
    lag_m: np.ndarray
    applied_outside_kg: float
    applied_total_kg: float
    duration_s: float
    wall_s: float
    n_fixes: int
    extra: dict[str, Any] = field(default_factory=dict)


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.hypot(v[0], v[1]))
    return v / n if n > 0 else np.array([1.0, 0.0])


def build_path(job: JobPackage, cfg: SimConfig, rng: np.random.Generator) -> SimPath:
    """Straight runs through consecutive same-swath cells, Bezier turns between runs."""
    c = np.asarray(job.corners_utm, dtype=float).reshape(-1, 4, 2)
    cent = c.mean(axis=1)
    sw = np.asarray(job.swath)
    n = len(sw)
    breaks = np.flatnonzero(np.diff(sw) != 0) + 1
    starts = np.concatenate([[0], breaks])
    ends = np.concatenate([breaks, [n]])
    vmax = cfg.speed_max_kmh / 3.6
    vmin = cfg.speed_min_kmh / 3.6
    # headland run-in: reach working speed (turns are driven slowly), let the speed
    # filter settle, then the look-ahead distance, before the first cell
    run_in = (
        cfg.run_in_m
        if cfg.run_in_m is not None
        else (vmax**2 - vmin**2) / (2 * cfg.accel_m_s2) + vmax * (job.lag_s + 1.6) + 2.0
    )
    xs: list[np.ndarray] = []
    ys: list[np.ndarray] = []
    rid: list[np.ndarray] = []
    cell_a = np.zeros(n)
    cell_b = np.zeros(n)
    run_of_cell = np.zeros(n, dtype=int)
    s_total = 0.0
    prev_end: np.ndarray | None = None
    prev_u: np.ndarray | None = None
    for r, (i0, i1) in enumerate(zip(starts, ends, strict=True)):
        if i1 - i0 >= 2:
            u = _unit(cent[i1 - 1] - cent[i0])
        else:
            e = c[i0, 1] - c[i0, 0]
            f = c[i0, 2] - c[i0, 1]
            u = _unit(e if np.hypot(*e) >= np.hypot(*f) else f)
            if prev_u is not None and np.dot(u, prev_u) > 0:
                u = -u
        o = cent[i0:i1].mean(axis=0)
        proj = (c[i0:i1] - o) @ u  # (k, 4)
        a = proj.min(axis=1)
        b = proj.max(axis=1)
        p0 = o + (a[0] - run_in) * u
        p1 = o + (b[-1] + run_in) * u
        if prev_end is not None and prev_u is not None:
            d = float(np.hypot(*(p0 - prev_end)))
            k = max(d * 0.6, 3.0)
            tt = np.linspace(0, 1, 25)[1:-1, None]
            q0, q1, q2, q3 = prev_end, prev_end + k * prev_u, p0 - k * u, p0
            bez = (
                (1 - tt) ** 3 * q0
                + 3 * (1 - tt) ** 2 * tt * q1
                + 3 * (1 - tt) * tt**2 * q2
                + tt**3 * q3
            )
            seg = np.vstack([prev_end, bez])
            xs.append(seg[:, 0])
            ys.append(seg[:, 1])
            rid.append(np.full(len(seg), -1))
            s_total += float(np.hypot(*np.diff(np.vstack([seg, p0]), axis=0).T).sum())
        # the run itself: start, end (fine resampling happens below)
        xs.append(np.array([p0[0], p1[0]]))
        ys.append(np.array([p0[1], p1[1]]))
        rid.append(np.array([r, r]))
        cell_a[i0:i1] = s_total + (a - (a[0] - run_in))
        cell_b[i0:i1] = s_total + (b - (a[0] - run_in))
        run_of_cell[i0:i1] = r
        s_total += float(np.hypot(*(p1 - p0)))
        prev_end, prev_u = p1, u
    vx = np.concatenate(xs)
    vy = np.concatenate(ys)
    vr = np.concatenate(rid)
    vs = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(vx), np.diff(vy)))])
    # segment heading: the heading of the segment leaving each vertex
    hd = np.arctan2(np.diff(vx), np.diff(vy))
    hd = np.concatenate([hd, hd[-1:]])
    n_runs = len(starts)
    lo, hi = cfg.speed_min_kmh / 3.6, cfg.speed_max_kmh / 3.6
    run_speed = rng.uniform(lo, hi, n_runs)
    if n_runs >= 3:  # make sure both ends of the range are driven
        run_speed[0], run_speed[1] = lo, hi
    return SimPath(vs, vx, vy, hd, vr, cell_a, cell_b, run_of_cell, run_speed)


def speed_profile(path: SimPath, cfg: SimConfig, rng: np.random.Generator) -> tuple:
    """Speed on a 0.1 m grid: run speeds with a slow wobble, turns at the low end,
    acceleration-limited both ways; returns (s grid, v grid, t grid)."""
    ds = 0.1
    sg = np.arange(0.0, path.s[-1] + ds, ds)
    seg = np.clip(np.searchsorted(path.s, sg, side="right") - 1, 0, len(path.s) - 1)
    run = path.run_id[seg]
    lo, hi = cfg.speed_min_kmh / 3.6, cfg.speed_max_kmh / 3.6
    v = np.where(run >= 0, path.run_speed[np.maximum(run, 0)], lo)
    ph = rng.uniform(0, 2 * np.pi)
    v = v * (1 + cfg.speed_wobble * np.sin(sg / 37.0 + ph) * (run >= 0))
    v = np.clip(v, lo, hi)
    a = cfg.accel_m_s2
    # v^2 <= v_prev^2 + 2 a ds forward and backward
    v2 = v * v
    for _ in range(2):
        for rng_dir in (1, -1):
            arr = v2 if rng_dir == 1 else v2[::-1]
            out = arr.copy()
            # vectorised with a running minimum of (v^2 - 2 a s) trick
            idx = np.arange(len(arr)) * ds * 2 * a
            out = np.minimum(arr, np.minimum.accumulate(arr - idx) + idx)
            v2 = out if rng_dir == 1 else out[::-1]
    v = np.sqrt(np.maximum(v2, 1e-4))
    t = np.concatenate([[0.0], np.cumsum(ds / (0.5 * (v[1:] + v[:-1])))])
    return sg, v, t


def _interp_path(path: SimPath, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    x = np.interp(s, path.s, path.x)
    y = np.interp(s, path.s, path.y)
    seg = np.clip(np.searchsorted(path.s, s, side="right") - 1, 0, len(path.s) - 1)
    return x, y, path.heading[seg]


def _flow_g_min(cal: Any, rpm: np.ndarray) -> np.ndarray:
    if getattr(cal, "kind", "linear") == "table":
        gpr = np.interp(rpm, np.asarray(cal.rpm), np.asarray(cal.g_per_rev))
        return np.maximum(gpr * rpm, 0.0)
    return np.maximum(cal.slope_g_min_per_rpm * rpm + cal.intercept_g_min, 0.0)


def _quad_area(c: np.ndarray) -> np.ndarray:
    x, y = c[:, 0::2], c[:, 1::2]
    return 0.5 * np.abs((x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y).sum(axis=1))


def simulate(
    job: JobPackage,
    cfg: SimConfig,
    sink: Any | None = None,
    t0: float | None = None,
    max_runs: int | None = None,
) -> SimResult:
    """Drive the job once; ``sink(records)`` receives telemetry record batches (queue.put_many)."""
    wall0 = time.perf_counter()
    rng = np.random.default_rng(cfg.seed)
    path = build_path(job, cfg, rng)
    sg, vg, tg = speed_profile(path, cfg, rng)
    if max_runs is not None:
        run_ok = path.run_of_cell < max_runs
        n_cells_used = int(run_ok.sum())
        s_end = (
            float(path.cell_b[n_cells_used - 1]) + (path.cell_a[0] if n_cells_used else 0.0)
            if n_cells_used
            else 0.0
        )
        t_end = float(np.interp(s_end, sg, tg))
    else:
        n_cells_used = job.n_cells
        t_end = float(tg[-1])
    dt = 1.0 / cfg.motor_hz
    ratio = int(round(cfg.motor_hz / cfg.gnss_hz))
    n_steps = int(t_end / dt)
    tk = (np.arange(n_steps) + 0.5) * dt  # midpoint of each motor period
    # GNSS fixes, vectorised noise
    fk = np.arange(0, n_steps, ratio)
    t_fix = fk * dt
    s_fix = np.interp(t_fix, tg, sg)
    fx, fy, fh = _interp_path(path, s_fix)
    nf = len(fk)
    fx = fx + rng.normal(0, cfg.gnss_noise_m, nf)
    fy = fy + rng.normal(0, cfg.gnss_noise_m, nf)
    fv = np.maximum(np.interp(s_fix, sg, vg) + rng.normal(0, cfg.speed_noise_m_s, nf), 0.0)
    fc = np.degrees(fh) % 360 + rng.normal(0, cfg.course_noise_deg, nf)
    # the agent's own pipeline and motor loop
    settings = job.controller
    if cfg.controller:
        settings = ControllerSettings(name=cfg.controller, params={}, period_s=dt)
    t50 = closed_loop_t50_s(settings, dt)
    t50_stop = closed_loop_t50_s(settings, dt, 100.0, 0.0)
    rcfg = RuntimeConfig(
        lag_compensation=cfg.lag_compensation,
        response_s=t50,
        stop_extra_s=max(0.0, t50_stop - t50) if cfg.edge_stop else 0.0,
        gnss_period_s=1.0 / cfg.gnss_hz,
    )
    pipe = Pipeline(job, rcfg)
    ctrl = build_controller(settings)
    plant = FastPlant2(dt)
    cstep, pstep = ctrl.step, plant.step
    rpm = np.zeros(n_steps)
    duty = np.zeros(n_steps)
    y = 0.0
    sp = 0.0
    pos = pipe.on_position
    fxl, fyl, fvl, fcl = fx.tolist(), fy.tolist(), fv.tolist(), fc.tolist()
    batch: list[dict] = []
    tbase = t0 if t0 is not None else time.time()
    j = 0
    for k0 in range(0, n_steps, ratio):
        d = pos(k0 * dt, fxl[j], fyl[j], fvl[j], fcl[j], True)
        sp = d.target_rpm if d.metering else 0.0
        if sink is not None:
            batch.append(make_record(pipe, d, None, y, ctrl.output, True, tbase + k0 * dt))
            if len(batch) >= 200:
                sink(batch)
                batch = []
        j += 1
        for k in range(k0, min(k0 + ratio, n_steps)):
            y0 = y
            u = cstep(sp, y, dt)
            y = pstep(u)
            rpm[k] = 0.5 * (y0 + y)
            duty[k] = u
    if sink is not None and batch:
        sink(batch)
    loop_wall = time.perf_counter() - wall0
    # where the fertilizer landed: metered at tk, lands at tk + lag at the outlet
    cal = calibration_from_dict(job.calibration)
    mass_g = _flow_g_min(cal, rpm) / 60.0 * dt
    s_land = np.interp(tk + job.lag_s, tg, sg) + job.antenna_forward_m
    v_land = np.interp(s_land, sg, vg)
    n = job.n_cells
    a, b = path.cell_a, path.cell_b
    ci = np.searchsorted(a, s_land, side="right") - 1
    ok = (ci >= 0) & (s_land < b[np.maximum(ci, 0)])
    seg = np.clip(np.searchsorted(path.s, s_land, side="right") - 1, 0, len(path.s) - 1)
    ok &= path.run_id[seg] >= 0
    m2 = np.bincount(ci[ok], weights=mass_g[ok], minlength=n)
    corners = np.asarray(job.corners_utm, dtype=float).reshape(-1, 8)
    area = _quad_area(corners)
    rates = np.asarray(job.rate_kg_ha)
    m1 = rates * area / 10.0  # seed 001 eq. 17: M v t l / 36 g == rate * area / 10
    used = np.zeros(n, dtype=bool)
    used[:n_cells_used] = True
    used &= m1 > 0
    acc = (1.0 - np.abs(m1 - m2) / np.where(m1 > 0, m1, 1.0)) * 100.0  # eq. 18
    # outside the field: test landing points not inside a cell that lies fully inside
    boundary = FieldBoundary(job.boundary_utm)
    cxy = corners.reshape(-1, 4, 2)
    shrink = cxy + 0.01 * (cxy.mean(axis=1, keepdims=True) - cxy)
    cell_in = boundary.contains_many(shrink.reshape(-1, 2)).reshape(-1, 4).all(axis=1)
    has_mass = mass_g > 0
    check = has_mass & ~(ok & cell_in[np.maximum(ci, 0)])
    lx, ly, _ = _interp_path(path, s_land[check])
    inside = boundary.contains_many(np.column_stack([lx, ly]))
    outside_g = float(mass_g[check][~inside].sum())
    # lag distance at cell borders with a real rate step, inside one run
    rate_land = np.where(
        v_land > 0.05, _flow_g_min(cal, rpm) / (6.0 * job.implement_width_m * v_land), 0
    )
    lags = []
    same_run = path.run_of_cell[1:] == path.run_of_cell[:-1]
    adjacent = np.abs(a[1:] - b[:-1]) < 1e-6
    r0, r1 = rates[:-1], rates[1:]
    step = np.abs(r1 - r0) >= cfg.border_min_step * np.maximum(r0, r1)
    borders = np.flatnonzero(same_run & adjacent & step & used[1:] & used[:-1])
    for i in borders:
        sb = b[i]
        # window: just before the border to the end of the next cell (the previous
        # border's transition must not count, even 4 m late without compensation)
        lo_i, hi_i = np.searchsorted(s_land, [sb - 0.8, b[i + 1]])
        if hi_i - lo_i < 3:
            continue
        seg_r = (rate_land[lo_i:hi_i] - r0[i]) / (r1[i] - r0[i])
        below = np.flatnonzero(seg_r < 0.5)  # first reach the old rate's side ...
        if len(below) == 0:
            continue
        cross = np.flatnonzero(seg_r[below[0] :] >= 0.5)  # ... then cross half-way
        if len(cross) == 0:
            continue
        j2 = below[0] + cross[0]
        f0, f1 = seg_r[j2 - 1], seg_r[j2]
        w = (0.5 - f0) / (f1 - f0) if f1 != f0 else 0.0
        sc = s_land[lo_i + j2 - 1] + w * (s_land[lo_i + j2] - s_land[lo_i + j2 - 1])
        lags.append(sc - sb)
    return SimResult(
        cell_accuracy_pct=acc[used],
        cell_m1_g=m1[used],
        cell_m2_g=m2[used],
        lag_m=np.asarray(lags),
        applied_outside_kg=outside_g / 1000.0,
        applied_total_kg=float(mass_g.sum()) / 1000.0,
        duration_s=t_end,
        wall_s=time.perf_counter() - wall0,
        n_fixes=nf,
        extra={
            "loop_wall_s": loop_wall,
            "response_s": t50,
            "look_ahead_s": pipe.look_ahead_time_s(),
            "cells": int(used.sum()),
            "seq": np.asarray(job.seq)[used],
            "rate": rates[used],
            "motor_steps": n_steps,
            "duty_max": float(duty.max()) if n_steps else 0.0,
        },
    )


def summary(
    res: SimResult, res_uncomp: SimResult | None, cfg: SimConfig, job: JobPackage
) -> dict[str, Any]:
    acc = res.cell_accuracy_pct
    lag = np.abs(res.lag_m)
    out = {
        "field": job.field_name,
        "cells": int(len(acc)),
        "controller": cfg.controller or job.controller.name,
        "lag_compensation": cfg.lag_compensation,
        "speed_kmh": [cfg.speed_min_kmh, cfg.speed_max_kmh],
        "mean_accuracy_pct": round(float(acc.mean()), 3) if len(acc) else None,
        "min_accuracy_pct": round(float(acc.min()), 3) if len(acc) else None,
        "p05_accuracy_pct": round(float(np.percentile(acc, 5)), 3) if len(acc) else None,
        "mean_lag_m": round(float(lag.mean()), 4) if len(lag) else None,
        "mean_signed_lag_m": round(float(res.lag_m.mean()), 4) if len(lag) else None,
        "lag_borders": int(len(lag)),
        "applied_outside_kg": round(res.applied_outside_kg, 4),
        "applied_total_kg": round(res.applied_total_kg, 3),
        "driven_s": round(res.duration_s, 1),
        "fixes": res.n_fixes,
        "wall_s": round(res.wall_s, 2),
        "response_s": round(res.extra["response_s"], 4),
        "look_ahead_s": round(res.extra["look_ahead_s"], 4),
    }
    if res_uncomp is not None:
        lu = np.abs(res_uncomp.lag_m)
        out["mean_lag_uncompensated_m"] = round(float(lu.mean()), 4) if len(lu) else None
        out["uncompensated_borders"] = int(len(lu))
        out["uncompensated_mean_accuracy_pct"] = round(
            float(res_uncomp.cell_accuracy_pct.mean()), 3
        )
    return out
