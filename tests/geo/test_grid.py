import math

import numpy as np
import pytest
import shapely
from fieldrx.geo import PlanningError
from fieldrx.geo.coverage import plan_coverage
from fieldrx.geo.crs import to_utm, utm_epsg_for
from fieldrx.geo.grid import build_grid
from shapely.geometry import box

from tests.geo.cases import (
    X0,
    Y0,
    check_cells_in_own_swath,
    check_grid,
    irregular,
    l_shape,
    plot_35x23,
    plot_35x23_rounded,
    pond_field,
    rect,
    u_shape,
)

FIELDS = {
    "rect": rect,
    "L": l_shape,
    "U": u_shape,
    "pond": pond_field,
    "plot": plot_35x23,
    "plot_rounded": plot_35x23_rounded,
    "irregular": irregular,
}


@pytest.mark.slow
@pytest.mark.parametrize("name", FIELDS)
@pytest.mark.parametrize("h", [0, 1, 2])
def test_fixed_fields_grid_invariants(name, h):
    f = FIELDS[name]()
    plan = plan_coverage(f, 2.3, "optimal", headland_passes=h)
    grid = build_grid(plan, f, 5.0)
    check_grid(grid, f, unworked_m2=plan.corner_loss_m2)
    check_cells_in_own_swath(grid, plan)
    # headland cells come first (headland_order "first"), then inner cells
    if h:
        first_inner = np.argmin(grid.headland)
        assert grid.headland[:first_inner].all() and not grid.headland[first_inner:].any()


def test_rectangle_cells_exact():
    f = rect(100, 23)  # 10 swaths of 2.3 m, 20 cells of 5 m each
    plan = plan_coverage(f, 2.3, "longest_edge")
    grid = build_grid(plan, f, 5.0)
    assert len(grid) == 200
    assert np.allclose(grid.area_m2, 11.5)
    # first cell at the sw corner, corners rear-right, front-right, front-left, rear-left
    assert np.allclose(
        grid.corners_utm[0], [[X0, Y0], [X0 + 5, Y0], [X0 + 5, Y0 + 2.3], [X0, Y0 + 2.3]]
    )
    # the second swath runs back west: its first cell is at the east end
    second = grid.corners_utm[grid.swath == 1][0]
    assert np.allclose(
        second,
        [[X0 + 100, Y0 + 4.6], [X0 + 95, Y0 + 4.6], [X0 + 95, Y0 + 2.3], [X0 + 100, Y0 + 2.3]],
    )
    assert np.array_equal(grid.index_in_swath[:20], np.arange(20))


def test_partial_cells_and_slivers():
    f = rect(101, 23)  # 1 m left over per swath: a 0.2-of-a-cell partial cell, kept
    grid = build_grid(plan_coverage(f, 2.3, "longest_edge"), f, 5.0, min_cell_fraction=0.1)
    assert len(grid) == 210
    assert np.isclose(grid.area_m2, 2.3).sum() == 10
    f2 = rect(100.3, 23)  # 0.3 m left over (0.06 of a cell): merged into its neighbour
    grid2 = build_grid(plan_coverage(f2, 2.3, "longest_edge"), f2, 5.0, min_cell_fraction=0.1)
    assert len(grid2) == 200
    assert np.isclose(grid2.area_m2, 5.3 * 2.3).sum() == 10
    assert grid2.area_m2.sum() == pytest.approx(f2.area)
    check_grid(grid2, f2)


def test_wgs84_corners_and_geojson():
    ll = box(11.0, 48.0, 11.002, 48.001)
    epsg = utm_epsg_for(11.001, 48.0005)
    f = to_utm(ll, epsg)
    plan = plan_coverage(f, 2.3, "optimal", headland_passes=1)
    grid = build_grid(plan, f, 5.0, epsg=epsg)
    c = grid.corners_wgs84
    assert c.shape == (len(grid), 4, 2)
    assert (np.abs(c[..., 0] - 11.001) < 0.002).all() and (
        np.abs(c[..., 1] - 48.0005) < 0.001
    ).all()
    fc = grid.to_geojson()
    assert fc["type"] == "FeatureCollection" and len(fc["features"]) == len(grid)
    assert [ft["properties"]["seq"] for ft in fc["features"]] == list(range(len(grid)))
    cells = shapely.from_geojson(
        [__import__("json").dumps(ft["geometry"]) for ft in fc["features"]]
    )
    # the cells hold the field less the headland corners the rounded ring cannot reach
    # (4 corners of (r + w/2)^2 (1 - pi/4) at the planner's 1.05 r: 0.3 % of this field)
    unworked = plan.corner_loss_m2 / f.area
    assert 0.001 < unworked < 0.005
    assert shapely.union_all(cells).area == pytest.approx(ll.area * (1 - unworked), rel=1e-3)


def test_bad_grid_parameters():
    f = plot_35x23()
    plan = plan_coverage(f, 2.3)
    with pytest.raises(PlanningError, match="cell_length_m must be >= 0.5"):
        build_grid(plan, f, 0.4)
    with pytest.raises(PlanningError, match="cell_length_m"):
        build_grid(plan, f, float("nan"))
    with pytest.raises(PlanningError, match="min_cell_fraction"):
        build_grid(plan, f, 5.0, min_cell_fraction=1.5)
    with pytest.raises(PlanningError, match="not the field"):
        build_grid(plan, rect(), 5.0)


@pytest.mark.slow
def test_too_many_cells_refused_before_allocating():
    side = math.sqrt(2_000 * 10_000)  # 2,000 ha at 0.5 m x 2.3 m: ~17 million cells
    f = box(X0, Y0, X0 + side, Y0 + side)
    plan = plan_coverage(f, 2.3, "longest_edge")
    import time

    t = time.perf_counter()
    with pytest.raises(PlanningError, match="more than 5000000"):
        build_grid(plan, f, 0.5)
    assert time.perf_counter() - t < 1.0


@pytest.mark.slow
def test_dense_noisy_boundary_is_planned_quickly_and_cells_fit_it():
    # a GNSS-traced boundary: 600 vertices ~1 m apart with 0.3 m noise
    import time

    from shapely.geometry import Polygon

    rng = np.random.default_rng(1)
    ang = np.linspace(0, 2 * math.pi, 600, endpoint=False)
    r = 120 * (1 + 0.05 * np.sin(5 * ang)) + rng.normal(0, 0.3, 600)
    f = Polygon(np.stack([X0 + 1.5 * r * np.cos(ang), Y0 + r * np.sin(ang)], 1))
    # CPU seconds of this process, not wall time: the bound is the algorithms' cost, which
    # a busy machine does not change (wall time took 28 s beside 6 busy processes)
    t = time.process_time()
    plan = plan_coverage(f, 2.3, "optimal", headland_passes=1)
    grid = build_grid(plan, f, 5.0)
    assert time.process_time() - t < 20.0
    # noise does not multiply the swaths: close to the strip count of the clean shape
    assert plan.n_swaths <= 1.15 * (2 * 120 * 1.05 / 2.3)
    check_grid(grid, f, unworked_m2=plan.corner_loss_m2)


@pytest.mark.parametrize(
    ("swath", "cell", "match"),
    [
        (0.05, 0.001, "cell_length_m must be >= 0.5 m"),  # sub-minimum cells are refused first
        (2.0, 0.3, "cell_length_m must be >= 0.5 m"),
        (0.05, 0.5, "more than 5000000"),
        (2.0, float("nan"), "cell_length_m must be >= 0.5 m"),
    ],
)
def test_grid_cost_refuses_before_planning(swath, cell, match):
    """The one cost estimate (API, import confirm, batch, CLI) counts every cell length: a
    length under the minimum used to skip the estimate, so a 5 cm swath planned for minutes
    before the grid refused it."""
    from fieldrx.geo.grid import check_grid_cost

    with pytest.raises(PlanningError, match=match):
        check_grid_cost(5_000_000.0, swath, cell)
    assert check_grid_cost(5_000_000.0, 2.0, 5.0) == pytest.approx(500_000.0)
