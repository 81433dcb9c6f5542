"""What both sensor kinds share in simulation: the planned path driven at the papers' test
speeds, one swath per speed in turn, sampled at the sensor rate."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from fieldrx_edge.estimate import KalmanSpeedFilter
from fieldrx_edge.gnss.utm import UtmProjection
from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.locate import FieldBoundary, locator_for_job
from fieldrx_edge.sim.simulator import SimConfig, build_path, speed_profile


@dataclass
class Drive:
    """Samples of one drive at ``hz``: time, true and noisy positions, speeds, heading, down."""

    t: np.ndarray
    x: np.ndarray  # true UTM position of the antenna
    y: np.ndarray
    heading: np.ndarray  # rad, clockwise from north
    v_true: np.ndarray
    v_raw: np.ndarray
    v_filt: np.ndarray
    down: np.ndarray  # on a swath run (implement down), not turning
    inside: np.ndarray
    lon: np.ndarray
    lat: np.ndarray
    run: np.ndarray
    tbase: float
    cell_seq: list[int | None]  # plan cell under the antenna (job progress, maps)

    @property
    def period_s(self) -> float | None:
        """The fix period every record carries (``fix_period_s``): 1 / hz."""
        return round(float(self.t[1] - self.t[0]), 6) if len(self.t) > 1 else None


def drive(
    job: JobPackage,
    speeds_kmh: list[float],
    hz: float,
    seed: int,
    gnss_noise_m: float = 0.02,
    speed_noise_m_s: float = 0.064,
    t0: float | None = None,
) -> Drive:
    """The job's planned path (seed 001's boustrophedon, fieldrx_edge.sim), swath k driven at
    ``speeds_kmh[k % len]`` with the simulator's 5 % wobble and 0.5 m/s^2 acceleration limit.
    Speed noise 0.064 m/s (1 sigma) is seed 001's measured raw GNSS speed error; the agent's
    Kalman filter (seed 001 eq. 14-15) smooths it as on the tractor."""
    rng = np.random.default_rng(seed)
    lo, hi = min(speeds_kmh), max(speeds_kmh)
    cfg = SimConfig(speed_min_kmh=min(lo, 3.0), speed_max_kmh=hi, seed=seed, speed_wobble=0.02)
    path = build_path(job, cfg, rng)
    path.run_speed = np.array(
        [speeds_kmh[k % len(speeds_kmh)] / 3.6 for k in range(len(path.run_speed))]
    )
    sg, vg, tg = speed_profile(path, cfg, rng)
    t = np.arange(0.0, float(tg[-1]), 1.0 / hz)
    s = np.interp(t, tg, sg)
    x = np.interp(s, path.s, path.x)
    y = np.interp(s, path.s, path.y)
    seg = np.clip(np.searchsorted(path.s, s, side="right") - 1, 0, len(path.s) - 1)
    heading = path.heading[seg]
    run = path.run_id[seg]
    v = np.interp(s, sg, vg)
    n = len(t)
    v_raw = np.maximum(v + rng.normal(0, speed_noise_m_s, n), 0.0)
    kf = KalmanSpeedFilter()
    v_filt = np.array([kf.update(float(z)) for z in v_raw])
    fb = FieldBoundary(job.boundary_utm)
    inside = np.array([fb.contains(a, b) for a, b in zip(x.tolist(), y.tolist(), strict=True)])
    xn = x + rng.normal(0, gnss_noise_m, n)
    yn = y + rng.normal(0, gnss_noise_m, n)
    proj = UtmProjection(job.utm_epsg)
    ll = np.array([proj.inverse(a, b) for a, b in zip(xn.tolist(), yn.tolist(), strict=True)])
    tbase = t0 if t0 is not None else time.time() - float(t[-1]) - 1.0
    loc, _ = locator_for_job(job)
    cells: list[int | None] = []
    for a, b, dn in zip(x.tolist(), y.tolist(), (run >= 0).tolist(), strict=True):
        k = loc.locate(a, b) if dn else -1
        cells.append(int(job.seq[k]) if k >= 0 else None)
    return Drive(
        t, x, y, heading, v, v_raw, v_filt, run >= 0, inside, ll[:, 0], ll[:, 1], run, tbase, cells
    )


def record(job: JobPackage, d: Drive, i: int, **fields: Any) -> dict[str, Any]:
    """A telemetry record dict (seq and machine_id are set by the queue) at sample ``i``."""
    from fieldrx_edge.protocol import TelemetryRecord

    rec = TelemetryRecord(
        machine_id=job.machine_id,
        seq=1,
        t=round(d.tbase + float(d.t[i]), 3),
        lon=float(d.lon[i]),
        lat=float(d.lat[i]),
        fix_quality=4,
        hdop=0.8,
        speed_raw_m_s=float(d.v_raw[i]),
        speed_filtered_m_s=float(d.v_filt[i]),
        heading_deg=float(np.degrees(d.heading[i]) % 360.0),
        job_id=job.job_id,
        cell_seq=d.cell_seq[i],
        implement_down=bool(d.down[i]),
        fix_period_s=d.period_s,
        **fields,
    )
    return rec.to_dict()


def cells_worked(recs: list[dict[str, Any]]) -> int:
    """Plan cells the implement worked in (a record with the implement down names the cell):
    what the server's job progress counts for a sensor kind (``fleet.ingest``)."""
    worked = {r.get("cell_seq") for r in recs if r.get("implement_down")}
    return len(worked - {None})


class Feed:
    """Records to ``sink`` (queue.put_many): batches of 200 as fast as possible, or, with
    ``realtime`` > 0, one at a time paced at that multiple of real time (so the fleet view
    watches the drive live, as ``simulate``'s ``--realtime`` does for prescription jobs).

    A record's time is its fix time (``protocol.TelemetryRecord``), paced or not: fixes
    0.1 s apart in simulated time stay 0.1 s apart in record time. A paced run moves the
    drive's time base so that the drive ends when the paced run will end, so no record is
    stamped after the moment it is sent (the rule of ``sim.simulator``; stamping the wall
    clock made every time-integrated figure 1 / realtime too small)."""

    def __init__(self, sink: Any | None, realtime: float = 0.0, drive: Drive | None = None) -> None:
        self.sink = sink
        self.realtime = realtime
        self.batch: list[dict[str, Any]] = []
        self.wall0 = time.time()
        self.shift = 0.0  # seconds added to each record's t (the drive's time base moves)
        if realtime > 0 and drive is not None and len(drive.t):
            t_end = float(drive.t[-1])
            self.shift = (self.wall0 + t_end / realtime - t_end) - drive.tbase

    def put(self, rec: dict[str, Any], t_sim: float) -> None:
        if self.sink is None:
            return
        if self.realtime > 0:
            ahead = self.wall0 + t_sim / self.realtime - time.time()
            if ahead > 0:
                time.sleep(ahead)
            rec["t"] = round(rec["t"] + self.shift, 3)
            self.sink([rec])
            return
        self.batch.append(rec)
        if len(self.batch) >= 200:
            self.sink(self.batch)
            self.batch = []

    def close(self) -> None:
        if self.sink is not None and self.batch:
            self.sink(self.batch)
            self.batch = []
