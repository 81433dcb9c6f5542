"""The agent and simulator on job packages built by the server's own planner and grid."""

import numpy as np
import pytest

pytest.importorskip("fieldrx.geo.grid")
shapely = pytest.importorskip("shapely")

from fieldrx.agronomy.cells import CellTable  # noqa: E402
from fieldrx.formats.jobpackage import build_job_package  # noqa: E402
from fieldrx.geo.coverage import plan_coverage  # noqa: E402
from fieldrx.geo.grid import build_grid  # noqa: E402
from fieldrx_edge.locate import CellLocator, FieldBoundary  # noqa: E402
from fieldrx_edge.metering import LinearCalibration  # noqa: E402
from fieldrx_edge.protocol import JobPackage  # noqa: E402
from fieldrx_edge.sim.simulator import SimConfig, simulate, summary  # noqa: E402

X0, Y0 = 500_000.0, 5_800_000.0


def irregular_job(headland_passes=0) -> tuple[JobPackage, object]:
    outer = [
        (X0, Y0),
        (X0 + 120, Y0 + 10),
        (X0 + 140, Y0 + 80),
        (X0 + 30, Y0 + 95),
        (X0 - 10, Y0 + 50),
    ]
    hole = [(X0 + 50, Y0 + 40), (X0 + 70, Y0 + 40), (X0 + 70, Y0 + 55), (X0 + 50, Y0 + 55)]
    field = shapely.Polygon(outer, [hole])
    plan = plan_coverage(field, 2.3, headland_passes=headland_passes)
    grid = build_grid(plan, field, 5.0)
    cx = grid.centroids_utm[:, 0]
    rates = np.round(600 + 250 * (0.5 + 0.5 * np.sign(np.sin((cx - X0) / 12.0))), 0)
    cells = CellTable.from_grid(grid, 32633).with_rates(rates)
    pkg = build_job_package(
        cells,
        field,
        job_id=1,
        machine_id=1,
        prescription_id=1,
        prescription_version=1,
        field_name="irregular",
        implement_width_m=2.3,
        lag_s=1.52,
        calibration=LinearCalibration(),
        controller={"name": "ladrc"},
        speed_min_m_s=3 / 3.6,
        speed_max_m_s=2.5,
    )
    return JobPackage.from_json(pkg.to_json()), field


def test_server_grid_irregular_field_with_hole():
    job, field = irregular_job()
    cfg = SimConfig(seed=0)
    res = simulate(job, cfg)
    out = summary(res, None, cfg, job)
    assert out["mean_accuracy_pct"] >= 98.0, out
    assert out["lag_borders"] >= 20 and out["mean_lag_m"] <= 0.28, out
    assert out["applied_outside_kg"] < 0.005 * out["applied_total_kg"]


def test_locator_and_boundary_agree_with_shapely_on_server_grid():
    job, field = irregular_job()
    loc = CellLocator(job.corners_utm)
    b = FieldBoundary(job.boundary_utm)
    c = np.asarray(job.corners_utm).reshape(-1, 4, 2)
    quads = [shapely.Polygon(q) for q in c]
    tree = shapely.STRtree(quads)
    rng = np.random.default_rng(0)
    pts = np.column_stack(
        [rng.uniform(X0 - 15, X0 + 145, 1500), rng.uniform(Y0 - 5, Y0 + 100, 1500)]
    )
    for x, y in pts:
        p = shapely.Point(x, y)
        assert b.contains(x, y) == field.contains(p)
        i = loc.locate(x, y)
        if i >= 0:
            assert quads[i].buffer(1e-6).contains(p)
        else:
            assert len(tree.query(p, predicate="within")) == 0
