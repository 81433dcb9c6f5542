"""The agent and simulator on job packages built by the server's own planner and grid."""

import numpy as np
import pytest

pytest.importorskip("fieldrx.geo.grid")
shapely = pytest.importorskip("shapely")

from fieldrx_edge.job_package import JobPackage  # noqa: E402
from fieldrx_edge.locate import CellLocator, FieldBoundary  # noqa: E402
from fieldrx_edge.sim.simulator import SimConfig, simulate, summary  # noqa: E402

from tests.edge.planned import X0, Y0, planned_job  # noqa: E402


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
    job, _ = planned_job(field, headland_passes, name="irregular")
    return job, field


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
