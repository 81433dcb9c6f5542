"""Job packages built by the server's own planner, grid and package builder (tests only)."""

from __future__ import annotations

import numpy as np
from fieldrx.agronomy.cells import CellTable
from fieldrx.formats.jobpackage import JobPackageSpec, build_job_package
from fieldrx.geo.coverage import plan_coverage
from fieldrx.geo.grid import build_grid
from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.metering import LinearCalibration

X0, Y0 = 500_000.0, 5_800_000.0  # a UTM 33N origin (EPSG 32633)


def planned_job(
    field,
    headland_passes: int = 0,
    period_m: float = 12.0,
    name: str = "field",  # noqa: ANN001
    width_m: float = 2.3,
) -> tuple[JobPackage, CellTable]:
    """Plan width_m x 5 m, rates alternating 600/850 kg/ha in bands period_m wide, package it."""
    plan = plan_coverage(field, width_m, headland_passes=headland_passes)
    grid = build_grid(plan, field, 5.0, epsg=32633)
    cx = grid.centroids_utm[:, 0]
    rates = np.round(600 + 250 * (0.5 + 0.5 * np.sign(np.sin((cx - X0) / period_m))), 0)
    cells = grid.with_rates(rates)
    pkg = build_job_package(
        cells,
        field,
        JobPackageSpec(
            job_id=1,
            machine_id=1,
            prescription_id=1,
            prescription_version=1,
            field_name=name,
            implement_width_m=width_m,
            lag_s=1.52,
            calibration=LinearCalibration(),
            controller={"name": "ladrc"},
            speed_min_m_s=3 / 3.6,
            speed_max_m_s=2.5,
        ),
    )
    return JobPackage.from_json(pkg.to_json()), cells
