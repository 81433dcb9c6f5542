"""Property-based tests over random convex and concave fields, with and without holes."""

import math

import numpy as np
import shapely
import shapely.affinity
from fieldrx.geo import PlanningError
from fieldrx.geo.coverage import plan_coverage, swath_footprints
from fieldrx.geo.grid import build_grid
from hypothesis import HealthCheck, assume, given, note, settings
from hypothesis import strategies as st
from shapely.geometry import MultiPoint, Polygon

from tests.geo.cases import X0, Y0, check_cells_in_own_swath, check_grid, check_plan

SETTINGS = settings(
    max_examples=18,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)


def _star(rng: np.random.Generator, n: int, r: float, cx: float, cy: float) -> Polygon:
    ang = np.sort(rng.uniform(0, 2 * math.pi, n))
    ang += np.linspace(0, 0.3, n)  # no two vertices at the same angle
    rad = r * rng.uniform(0.4, 1.0, n)
    return Polygon(np.stack([cx + rad * np.cos(ang), cy + rad * np.sin(ang)], 1))


@st.composite
def fields(draw, concave: bool, max_holes: int):
    seed = draw(st.integers(0, 2**31 - 1))
    n = draw(st.integers(3, 12))
    r = draw(st.floats(40.0, 200.0))
    w = draw(st.sampled_from([2.3, 4.0, 8.0]))
    rng = np.random.default_rng(seed)
    if concave:
        outer = _star(rng, max(n, 5), r, X0, Y0)
    else:
        pts = rng.uniform(-r, r, (max(n, 4), 2)) + (X0, Y0)
        outer = MultiPoint(pts).convex_hull
    outer = shapely.affinity.scale(outer, draw(st.floats(0.5, 2.0)), 1.0)
    outer = shapely.affinity.rotate(outer, draw(st.floats(0, 180)))
    assume(isinstance(outer, Polygon) and outer.is_valid and outer.area > 400)
    holes = []
    for _ in range(draw(st.integers(0, max_holes))):
        room = outer.buffer(-(0.15 * r + 3 * w))
        if room.is_empty:
            break
        x0, y0, x1, y1 = room.bounds
        cx, cy = rng.uniform(x0, x1), rng.uniform(y0, y1)
        hole = _star(rng, 6, 0.12 * r, cx, cy)
        if room.contains(hole) and all(hole.distance(h) > 3 * w for h in holes):
            holes.append(hole)
    field = Polygon(outer.exterior.coords, [h.exterior.coords for h in holes])
    assume(field.is_valid)
    return field, w


def _plan_or_skip(field, w, **kw):
    try:
        return plan_coverage(field, w, **kw)
    except PlanningError as exc:
        # only legitimate refusals: too narrow for the implement or no inner area
        assert "wider than the field" in str(exc) or "no inner area" in str(exc), str(exc)
        assume(False)


def _check_all(field, w, h, heading):
    note(f"field={field.wkt} w={w} h={h} heading={heading}")
    plan = _plan_or_skip(field, w, heading=heading, headland_passes=h)
    check_plan(plan, field)
    grid = build_grid(plan, field, 5.0)
    # the working area: the part of the field the implement sweeps
    working = shapely.union_all(swath_footprints(plan)).intersection(field).area
    check_grid(grid, field, min_cover=0.995 * working / field.area)
    check_cells_in_own_swath(grid, plan)
    assert working >= 0.9 * field.area
    return plan


@SETTINGS
@given(fields(concave=False, max_holes=0), st.sampled_from([0, 1]))
def test_convex_fields(fw, h):
    field, w = fw
    plan = _check_all(field, w, h, "optimal")
    le = _plan_or_skip(field, w, heading="longest_edge", headland_passes=h)
    assert plan.n_swaths <= le.n_swaths
    if h == 0:
        assert plan.coverage_pct > 99.999  # convex, no headland: the swaths cover everything


@SETTINGS
@given(fields(concave=True, max_holes=0), st.sampled_from([0, 1]))
def test_concave_fields(fw, h):
    field, w = fw
    plan = _check_all(field, w, h, "optimal")
    le = _plan_or_skip(field, w, heading="longest_edge", headland_passes=h)
    assert plan.n_swaths <= le.n_swaths


@SETTINGS
@given(fields(concave=True, max_holes=2), st.sampled_from([0, 1, 2]))
def test_fields_with_holes(fw, h):
    field, w = fw
    _check_all(field, w, h, "longest_edge")
