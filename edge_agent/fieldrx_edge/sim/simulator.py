"""A tractor driving a job: path, speed profile, GNSS noise, motor, fertilizer fall.

The simulated machine drives the job's cells in path order (straight swath
lines through the cells, Bezier turns between them) with a speed profile in
the requested range. At the GNSS rate it feeds noisy fixes to the agent's own
``runtime.Pipeline``; the named controller drives the seed 001 motor plant at
the motor rate. Fertilizer metered at time t lands at t + lag_s at the outlet
position of that moment (seed 001 sec. 2.3). What landed where is then
computed with the one as-applied kernel (``fieldrx_edge.asapplied``, also the
server's): per-cell mass against the theoretical mass (seed 001 eq. 17-18),
and the mass that fell outside the cells and the field; plus the lag distance
at every cell border with a rate step. The same kernel over the agent's own
records (``extra["logged_accuracy_pct"]``) is what the server's report will
compute from that telemetry.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from fieldrx_edge.asapplied import (
    Cells,
    RecordColumns,
    driven_length,
    landed_mass,
    landing_segments,
    m1_g,
    records_applied,
    theta_pct,
)
from fieldrx_edge.job_package import ControllerSettings, JobPackage
from fieldrx_edge.locate import boundary_rings
from fieldrx_edge.metering import calibration_from_dict, flow_g_min_many
from fieldrx_edge.motor import build_controller, closed_loop_t50_s
from fieldrx_edge.runtime import Measured, Pipeline, RuntimeConfig, make_record
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
    # None: the agent drives the motor directly. Else an object whose step(t, decision,
    # actual_rpm) returns the shaft target, e.g. isobus.pair.IsobusPair (TC -> CAN -> ECU)
    implement: Any = None
    lag_compensation: bool = True
    seed: int = 0
    accel_m_s2: float = 0.5
    speed_wobble: float = 0.05  # slow speed variation along a swath (fraction)
    run_in_m: float | None = None
    compare_runs: int = 20  # swath runs simulated without compensation for the comparison
    realtime: float = 0.0  # > 0: pace the drive at this multiple of real time (live telemetry)
    edge_stop: bool = True  # anticipate the coast-down at field edges (RuntimeConfig.stop_extra_s)
    # anticipate the spin-up from rest (RuntimeConfig.start_extra_s): first cells of a
    # swath gain ~2 %, but half the spin-up tail then lands before the field edge
    edge_start: bool = False
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


def _normal_toward(p: np.ndarray, q: np.ndarray, toward: np.ndarray) -> np.ndarray:
    e = q - p
    n = _unit(np.array([e[1], -e[0]]))
    return n if float(np.dot(n, toward)) >= 0 else -n


def _shared_edge(a: np.ndarray, b: np.ndarray, tol: float = 0.05) -> tuple | None:
    """The two corners cells a and b (4x2 each) have in common, if any."""
    d = np.hypot(a[:, None, 0] - b[None, :, 0], a[:, None, 1] - b[None, :, 1])
    ia = np.unique(np.argwhere(d < tol)[:, 0])
    if len(ia) < 2:
        return None
    return a[ia[0]], a[ia[1]]


def _run_waypoints(
    c: np.ndarray, cent: np.ndarray, prev_u: np.ndarray | None
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Entry and exit point of every cell of one run (consecutive cells of a swath).

    Consecutive cells share a cut edge across the swath; its midpoint is on the
    driving line and its normal is the direction of travel there. This follows
    straight swaths and curved headland rings alike. A cell without a shared
    edge (a swath interrupted by a hole, a one-cell run) is crossed along the
    run direction through its centroid.
    """
    k = len(c)
    mids: list[tuple[np.ndarray, np.ndarray] | None] = []
    for j in range(k - 1):
        e = _shared_edge(c[j], c[j + 1])
        if e is None:
            mids.append(None)
        else:
            p, q = e
            mids.append(((p + q) / 2, _normal_toward(p, q, cent[j + 1] - cent[j])))
    entry: list[np.ndarray | None] = [None] * k
    exit_: list[np.ndarray | None] = [None] * k
    for j in range(k):
        before = mids[j - 1] if j > 0 else None
        after = mids[j] if j < k - 1 else None
        if before is not None:
            entry[j] = before[0]
        if after is not None:
            exit_[j] = after[0]
    if k >= 2:
        run_u = _unit(cent[-1] - cent[0])
    else:
        e0, e1 = c[0, 1] - c[0, 0], c[0, 2] - c[0, 1]
        run_u = _unit(e0 if np.hypot(*e0) >= np.hypot(*e1) else e1)
        if prev_u is not None and float(np.dot(run_u, prev_u)) > 0:
            run_u = -run_u  # boustrophedon: the next swath goes back
    for j in range(k):
        before = mids[j - 1] if j > 0 else None
        after = mids[j] if j < k - 1 else None
        ent, ex = entry[j], exit_[j]
        if ent is not None and ex is None:
            assert before is not None  # entry[j] came from it
            u = before[1]
            ext = float(((c[j] - ent) @ u).max())
            exit_[j] = ent + ext * u
        elif ex is not None and ent is None:
            assert after is not None  # exit_[j] came from it
            u = after[1]
            ext = float(((ex - c[j]) @ u).max())
            entry[j] = ex - ext * u
        elif entry[j] is None:
            u = run_u
            if k >= 2:
                # local travel direction snapped to the cell's own axis: a headland ring's
                # corner cell is crossed along itself, not along the ring's chord
                t = _unit(cent[min(j + 1, k - 1)] - cent[max(j - 1, 0)])
                axes = [_unit(c[j, 1] - c[j, 0]), _unit(c[j, 2] - c[j, 1])]
                ax = max(axes, key=lambda a: abs(float(np.dot(a, t))))
                u = ax if float(np.dot(ax, t)) >= 0 else -ax
            proj = (c[j] - cent[j]) @ u
            entry[j] = cent[j] + float(proj.min()) * u
            exit_[j] = cent[j] + float(proj.max()) * u
    return entry, exit_  # type: ignore[return-value]


def build_path(job: JobPackage, cfg: SimConfig, rng: np.random.Generator) -> SimPath:
    """Runs through consecutive same-swath cells (cut-edge midpoints), Bezier turns between."""
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
        entry, exit_ = _run_waypoints(c[i0:i1], cent[i0:i1], prev_u)
        u0 = _unit(exit_[0] - entry[0])
        u1 = _unit(exit_[-1] - entry[-1])
        p0 = entry[0] - run_in * u0
        p1 = exit_[-1] + run_in * u1
        if prev_end is not None and prev_u is not None:
            d = float(np.hypot(*(p0 - prev_end)))
            kk = max(d * 0.6, 3.0)
            tt = np.linspace(0, 1, 25)[1:-1, None]
            q0, q1, q2, q3 = prev_end, prev_end + kk * prev_u, p0 - kk * u0, p0
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
        pts = [p0]
        ia = np.zeros(i1 - i0, dtype=int)
        ib = np.zeros(i1 - i0, dtype=int)
        for j in range(i1 - i0):
            if float(np.hypot(*(entry[j] - pts[-1]))) > 1e-6:
                pts.append(entry[j])
            ia[j] = len(pts) - 1
            pts.append(exit_[j])
            ib[j] = len(pts) - 1
        pts.append(p1)
        arr = np.array(pts)
        cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(arr, axis=0).T))])
        xs.append(arr[:, 0])
        ys.append(arr[:, 1])
        rid.append(np.full(len(arr), r))
        cell_a[i0:i1] = s_total + cum[ia]
        cell_b[i0:i1] = s_total + cum[ib]
        run_of_cell[i0:i1] = r
        s_total += float(cum[-1])
        prev_end, prev_u = p1, u1
    vx = np.concatenate(xs)
    vy = np.concatenate(ys)
    vr = np.concatenate(rid)
    vs = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(vx), np.diff(vy)))])
    # drop zero-length segments (duplicate vertices) so interpolation stays monotonic
    keep = np.concatenate([np.diff(vs) > 1e-9, [True]])
    vx, vy, vr, vs = vx[keep], vy[keep], vr[keep], vs[keep]
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


def interp_path(path: SimPath, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position and heading (rad clockwise from north) at path distances ``s``."""
    x = np.interp(s, path.s, path.x)
    y = np.interp(s, path.s, path.y)
    seg = np.clip(np.searchsorted(path.s, s, side="right") - 1, 0, len(path.s) - 1)
    return x, y, path.heading[seg]


_interp_path = interp_path  # old private name, kept for callers not yet moved


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
    fx, fy, fh = interp_path(path, s_fix)
    # the implement is lowered shortly before a run's first cell (so the look-ahead
    # can start metering) and raised after its last; turns and run-ins are driven raised
    fseg = np.clip(np.searchsorted(path.s, s_fix, side="right") - 1, 0, len(path.s) - 1)
    frun = path.run_id[fseg]
    n_runs = int(path.run_of_cell.max()) + 1 if job.n_cells else 0
    first = np.searchsorted(path.run_of_cell, np.arange(n_runs), side="left")
    last = np.searchsorted(path.run_of_cell, np.arange(n_runs), side="right") - 1
    pre = cfg.speed_max_kmh / 3.6 * (job.lag_s + 0.5) + max(0.0, job.antenna_forward_m) + 1.0
    lo_s = path.cell_a[first] - pre
    hi_s = path.cell_b[last] + 0.3
    rr = np.maximum(frun, 0)
    fdown = ((frun >= 0) & (s_fix >= lo_s[rr]) & (s_fix <= hi_s[rr])).tolist()
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
    t50_start = closed_loop_t50_s(settings, dt, 0.0, 100.0)
    rcfg = RuntimeConfig(
        lag_compensation=cfg.lag_compensation,
        response_s=t50,
        stop_extra_s=max(0.0, t50_stop - t50) if cfg.edge_stop else 0.0,
        start_extra_s=max(0.0, t50_start - t50) if cfg.edge_start else 0.0,
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
    # A record's time is its fix time (protocol.TelemetryRecord): simulated time since the
    # start of the drive, k0 * dt, on a base chosen so the drive ends when the run ends:
    # now (as fast as possible) or when the paced run will end. Paced at `realtime` x,
    # fixes 0.1 s apart in simulated time go out 0.1 / realtime s apart in wall time, yet
    # stay 0.1 s apart in record time, and no record is stamped after the moment it is
    # sent. (Stamping the wall clock made the report 1 / realtime too low.)
    pace = cfg.realtime
    wall_start = time.time()
    tbase = t0 if t0 is not None else wall_start + (t_end / pace if pace > 0 else 0.0) - t_end
    period = 1.0 / cfg.gnss_hz
    batch_n = 1 if pace > 0 else 200
    # the agent's log as the server will see it (one row per fix): the as-applied kernel
    # over it is what the server's report computes from the records (``logged`` figures)
    index_of = {int(sq): i for i, sq in enumerate(job.seq)}
    log_xyh: list[tuple[float, float, float]] = []
    log_rpm: list[float] = []
    log_own: list[int] = []
    j = 0
    for k0 in range(0, n_steps, ratio):
        down = fdown[j]
        d = pos(k0 * dt, fxl[j], fyl[j], fvl[j], fcl[j], down)
        log_xyh.append(
            (
                np.nan if d.x is None else d.x,
                np.nan if d.y is None else d.y,
                0.0 if d.heading_deg is None else d.heading_deg,
            )
        )
        log_rpm.append(y)
        log_own.append(-1 if d.cell_seq is None else index_of.get(int(d.cell_seq), -1))
        sp = d.target_rpm if d.metering else 0.0
        if cfg.implement is not None:
            sp = cfg.implement.step(k0 * dt, d, y)
        if sink is not None:
            if pace > 0:
                ahead = wall_start + k0 * dt / pace - time.time()
                if ahead > 0:
                    time.sleep(ahead)
            batch.append(
                make_record(
                    pipe,
                    d,
                    None,
                    Measured(y, ctrl.output, down, tbase + k0 * dt, fix_period_s=period),
                )
            )
            if len(batch) >= batch_n:
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
    # what landed where (seed 001 eq. 16-18), with the one as-applied kernel: metered
    # during motor step k ([k dt, (k+1) dt]) at the calibration's flow, landing T_lag later
    # along the exact track, antenna_forward_m ahead, split among the cells' polygons
    cal = calibration_from_dict(job.calibration)
    flow_g_min = flow_g_min_many(cal, rpm)
    mass_g = flow_g_min / 60.0 * dt
    n = job.n_cells
    a, b = path.cell_a, path.cell_b
    rates = np.asarray(job.rate_kg_ha)
    cells = Cells.build(
        job.corners_utm,
        job.swath,
        job.cell_shapes(),
        [ring for ring, _ in boundary_rings(job.boundary_utm)],
    )
    m1 = m1_g(rates, job.implement_width_m, driven_length(cells))
    used = np.zeros(n, dtype=bool)
    used[:n_cells_used] = True
    used &= m1 > 0
    gx, gy, gh = interp_path(path, sg)
    own_fix = np.asarray(log_own, dtype=np.int64)
    # the motor's mass summed per fix period (its 10 motor steps), spread along that
    # period's landing segment (0.1 s, <= 0.25 m at 9 km/h): the 100 Hz flow's shape inside
    # a period is below the kernel's resolution, and this keeps the cost of the drive's
    # bookkeeping at the log's (a 20 ha job: ~1.2 M motor steps)
    n_per = len(own_fix)
    per = np.minimum(np.arange(n_steps) // ratio, n_per - 1)
    mass_per = np.bincount(per, weights=mass_g, minlength=n_per)
    t_per = np.arange(n_per) * ratio * dt
    dt_per = np.bincount(per, minlength=n_per) * dt
    p0, p1, known = landing_segments(
        t_per, dt_per, tg, gx, gy, np.degrees(gh), job.lag_s, job.antenna_forward_m
    )
    m2, outside_g = landed_mass(cells, np.where(known, mass_per, 0.0), p0, p1, own_fix)
    outside_g += float(mass_per[~known].sum())
    acc = theta_pct(m1, m2)  # eq. 18
    # the same kernel over the agent's log (fix time, position, heading, shaft speed)
    t_fix_log = np.arange(0, n_steps, ratio) * dt
    lxyh = np.asarray(log_xyh, dtype=float).reshape(-1, 3)
    log_cols = RecordColumns(
        t_fix_log, np.full(len(t_fix_log), 1.0 / cfg.gnss_hz), lxyh[:, 0], lxyh[:, 1],
        lxyh[:, 2], np.asarray(log_rpm), own_fix, np.zeros(len(t_fix_log)),
    )  # fmt: skip
    logged = records_applied(cells, log_cols, cal, job.lag_s, job.antenna_forward_m)
    logged_acc = theta_pct(m1, logged.m2_g)
    s_land = np.interp(tk + job.lag_s, tg, sg) + job.antenna_forward_m
    v_land = np.interp(s_land, sg, vg)
    # lag distance at cell borders with a real rate step, inside one run
    rate_land = np.where(v_land > 0.05, flow_g_min / (6.0 * job.implement_width_m * v_land), 0)
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
            # the kernel over the agent's records (what the server's report computes)
            "logged_m2_g": logged.m2_g[used],
            "logged_accuracy_pct": logged_acc[used],
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
        # the as-applied kernel over the agent's records: what the server's report shows
        "logged_mean_accuracy_pct": round(float(res.extra["logged_accuracy_pct"].mean()), 3)
        if len(acc)
        else None,
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
