"""Drive a job in simulation and write what the receiver would say (NMEA log)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from fieldrx_edge.gnss.utm import UtmProjection
from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.sim import nmea
from fieldrx_edge.sim.simulator import SimConfig, build_path, interp_path, speed_profile


def drive_fixes(
    job: JobPackage, cfg: SimConfig, max_s: float | None = None
) -> dict[str, np.ndarray]:
    """Noisy fixes along the job's path at cfg.gnss_hz: t, x, y, lon, lat, speed, course."""
    rng = np.random.default_rng(cfg.seed)
    path = build_path(job, cfg, rng)
    sg, vg, tg = speed_profile(path, cfg, rng)
    t_end = float(tg[-1]) if max_s is None else min(float(tg[-1]), max_s)
    t = np.arange(0.0, t_end, 1.0 / cfg.gnss_hz)
    s = np.interp(t, tg, sg)
    x, y, h = interp_path(path, s)
    n = len(t)
    x = x + rng.normal(0, cfg.gnss_noise_m, n)
    y = y + rng.normal(0, cfg.gnss_noise_m, n)
    v = np.maximum(np.interp(s, sg, vg) + rng.normal(0, cfg.speed_noise_m_s, n), 0.0)
    c = (np.degrees(h) + rng.normal(0, cfg.course_noise_deg, n)) % 360.0
    proj = UtmProjection(job.utm_epsg)
    ll = np.array([proj.inverse(a, b) for a, b in zip(x.tolist(), y.tolist(), strict=True)])
    return {
        "t": t,
        "x": x,
        "y": y,
        "lon": ll[:, 0],
        "lat": ll[:, 1],
        "speed": v,
        "course": c,
        "speed_true": np.interp(s, sg, vg),
    }


def write_nmea_log(
    job: JobPackage,
    path: str | Path,
    cfg: SimConfig | None = None,
    t0: float = 1_763_700_000.0,
    max_s: float | None = None,
    vtg: bool = True,
    talker: str = "GN",
) -> int:
    """RMC + GGA (+ VTG) per epoch; returns the number of epochs written."""
    cfg = cfg or SimConfig()
    f = drive_fixes(job, cfg, max_s)
    lines = []
    for t, lon, lat, v, c in zip(
        f["t"].tolist(),
        f["lon"].tolist(),
        f["lat"].tolist(),
        f["speed"].tolist(),
        f["course"].tolist(),
        strict=True,
    ):
        lines.append(nmea.rmc(t0 + t, lat, lon, v, c, talker=talker))
        lines.append(nmea.gga(t0 + t, lat, lon, talker=talker))
        if vtg:
            lines.append(nmea.vtg(v, c, talker=talker))
    Path(path).write_text("\r\n".join(lines) + "\r\n")
    return len(f["t"])
