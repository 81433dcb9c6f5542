"""Synthetic job packages for simulation and tests (no server, no planner).

A rectangular field cut into boustrophedon swaths along its long edge and
cells every ``cell_length_m`` (seed 001 sec. 1.2: 2.3 m implement, 5 m cells),
numbered in path order with counter-clockwise corners. Rates form a smooth
random surface inside the range the meter can hold at every planned speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from fieldrx_edge.gnss.utm import UtmProjection
from fieldrx_edge.job_package import ControllerSettings, JobPackage


@dataclass(frozen=True)
class RectField:
    """A synthetic rectangular job: the field, its cells and rates, the machine's job
    settings. ``hole`` = (x0, y0, x1, y1) relative to the origin."""

    length_m: float = 35.0
    width_m: float = 23.0
    implement_width_m: float = 2.3
    cell_length_m: float = 5.0
    rate_range_kg_ha: tuple[float, float] = (600.0, 850.0)
    lag_s: float = 1.52
    seed: int = 0
    utm_epsg: int = 32633
    origin: tuple[float, float] = (500_000.0, 5_800_000.0)
    hole: tuple[float, float, float, float] | None = None
    controller: str = "ladrc"
    job_id: int = 1
    machine_id: int = 1
    speed_min_m_s: float = 3 / 3.6
    speed_max_m_s: float = 9 / 3.6
    roughness: float = 0.3


def rect_job(spec: RectField = RectField()) -> JobPackage:
    """A ``spec.length_m`` x ``spec.width_m`` field cut into swaths and cells."""
    length_m, width_m, implement_width_m = spec.length_m, spec.width_m, spec.implement_width_m
    cell_length_m, hole, origin = spec.cell_length_m, spec.hole, spec.origin
    ox, oy = origin
    n_sw = max(1, math.ceil(width_m / implement_width_m - 1e-9))
    n_c = max(1, math.ceil(length_m / cell_length_m - 1e-9))
    xa = np.minimum(np.arange(n_c) * cell_length_m, length_m)
    xb = np.minimum(xa + cell_length_m, length_m)
    rows = []
    for j in range(n_sw):
        ya, yb = j * implement_width_m, (j + 1) * implement_width_m
        order = range(n_c) if j % 2 == 0 else range(n_c - 1, -1, -1)
        for i in order:
            rows.append((j, xa[i], xb[i], ya, yb))
    arr = np.array(rows, dtype=float)
    if hole is not None:
        hx0, hy0, hx1, hy1 = hole
        cx = (arr[:, 1] + arr[:, 2]) / 2
        cy = (arr[:, 3] + arr[:, 4]) / 2
        keep = ~((cx > hx0) & (cx < hx1) & (cy > hy0) & (cy < hy1))
        arr = arr[keep]
    rng = np.random.default_rng(spec.seed)
    lo, hi = spec.rate_range_kg_ha
    cx = (arr[:, 1] + arr[:, 2]) / 2
    cy = (arr[:, 3] + arr[:, 4]) / 2
    ph = rng.uniform(0, 2 * math.pi, 4)
    surf = (
        np.sin(cx / 23.0 + ph[0]) * np.cos(cy / 17.0 + ph[1])
        + 0.5 * np.sin(cx / 9.0 + ph[2])
        + 0.5 * np.cos(cy / 7.0 + ph[3])
        + rng.normal(0, spec.roughness, len(arr))  # cell-to-cell variation
    )
    surf = (surf - surf.min()) / max(np.ptp(surf), 1e-9)
    rates = np.round((lo + surf * (hi - lo)) / 5.0) * 5.0
    x0, x1 = ox + arr[:, 1], ox + arr[:, 2]
    y0, y1 = oy + arr[:, 3], oy + arr[:, 4]
    corners = np.stack([x0, y0, x1, y0, x1, y1, x0, y1], axis=1)
    proj = UtmProjection(spec.utm_epsg)
    flat = corners.reshape(-1, 2)
    wgs = np.array([proj.inverse(x, y) for x, y in flat])
    outer = [
        [ox, oy],
        [ox + length_m, oy],
        [ox + length_m, oy + width_m],
        [ox, oy + width_m],
        [ox, oy],
    ]
    rings = [outer]
    if hole is not None:
        hx0, hy0, hx1, hy1 = hole
        rings.append(
            [
                [ox + hx0, oy + hy0],
                [ox + hx0, oy + hy1],
                [ox + hx1, oy + hy1],
                [ox + hx1, oy + hy0],
                [ox + hx0, oy + hy0],
            ]
        )
    return JobPackage(
        job_id=spec.job_id,
        machine_id=spec.machine_id,
        prescription_id=1,
        prescription_version=1,
        field_name=f"sim {length_m:g} m x {width_m:g} m",
        utm_epsg=spec.utm_epsg,
        implement_width_m=implement_width_m,
        lag_s=spec.lag_s,
        calibration={"kind": "linear"},
        controller=ControllerSettings(name=spec.controller),
        boundary_utm={"type": "Polygon", "coordinates": rings},
        seq=list(range(1, len(arr) + 1)),
        swath=[int(v) for v in arr[:, 0]],
        rate_kg_ha=[float(r) for r in rates],
        corners_utm=[float(v) for v in corners.reshape(-1)],
        corners_wgs84=[float(v) for v in wgs.reshape(-1)],
        speed_min_m_s=spec.speed_min_m_s,
        speed_max_m_s=spec.speed_max_m_s,
        product="urea (sim)",
    ).seal()


def field_20ha(seed: int = 0, **kw: object) -> JobPackage:
    """500 m x 400.2 m (174 swaths of 2.3 m): 20.01 ha, 17,400 cells, with a rough
    rate map (about a third of the cell borders step by >= 8 %)."""
    kw.setdefault("roughness", 1.0)
    return rect_job(RectField(length_m=500.0, width_m=174 * 2.3, seed=seed, **kw))  # type: ignore[arg-type]
