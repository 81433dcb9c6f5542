import numpy as np
import pytest
from fieldrx_edge.locate import CellLocator, FieldBoundary, Where
from hypothesis import given, settings
from hypothesis import strategies as st

from .jobfactory import holed_field, trial_plot

OX, OY = 500_000.0, 5_800_000.0


def test_locator_matches_naive_scan_on_random_points():
    job = holed_field()
    loc = CellLocator(job.corners_utm)
    rng = np.random.default_rng(1)
    pts = np.column_stack([rng.uniform(OX - 5, OX + 65, 3000), rng.uniform(OY - 5, OY + 28, 3000)])
    for x, y in pts:
        a = loc.locate(x, y)
        b = loc.locate_naive(x, y)
        assert a == b


@settings(max_examples=50, deadline=None)
@given(x=st.floats(-10, 70), y=st.floats(-10, 33))
def test_locator_result_contains_the_point(x, y):
    job = holed_field()
    loc = CellLocator(job.corners_utm)
    i = loc.locate(OX + x, OY + y)
    c = np.asarray(job.corners_utm).reshape(-1, 8)
    if i >= 0:
        q = c[i]
        assert q[0::2].min() <= OX + x <= q[0::2].max()
        assert q[1::2].min() <= OY + y <= q[1::2].max()
    else:
        assert loc.locate_naive(OX + x, OY + y) == -1


def test_path_following_is_forward_and_needs_no_fallback():
    job = trial_plot()
    loc = CellLocator(job.corners_utm)
    c = np.asarray(job.corners_utm).reshape(-1, 4, 2).mean(axis=1)
    seen = []
    for k in range(job.n_cells):  # drive through every centre in path order, 20 points per cell
        nxt = c[min(k + 1, job.n_cells - 1)]
        for f in np.linspace(0, 0.49, 10):
            x, y = c[k] + f * (nxt - c[k]) * (
                1 if job.swath[min(k + 1, job.n_cells - 1)] == job.swath[k] else 0
            )
            seen.append(loc.locate(x, y))
        loc.finished[k] = True
    assert sorted(set(seen)) == list(range(job.n_cells))
    assert loc.fallbacks <= job.n_cells // 7  # at most the swath changes (7 cells per swath)


def test_finished_cells_are_dropped_but_reported_by_fallback():
    job = trial_plot()
    loc = CellLocator(job.corners_utm)
    c = np.asarray(job.corners_utm).reshape(-1, 4, 2).mean(axis=1)
    assert loc.locate(*c[3]) == 3
    loc.finished[3] = True
    loc.current = 0
    assert loc.locate(*c[3]) == 3  # still found (overlap control needs it) via the grid
    assert loc.finished[loc.locate(*c[3])]
    assert loc.locate(*c[4]) == 4


def test_boundary_outside_hole_inside():
    job = holed_field()
    b = FieldBoundary(job.boundary_utm)
    assert b.where(OX + 5, OY + 5) == Where.INSIDE
    assert b.where(OX + 30, OY + 11) == Where.HOLE
    assert b.where(OX - 1, OY + 5) == Where.OUTSIDE
    assert b.where(OX + 61, OY + 5) == Where.OUTSIDE
    assert b.where(OX + 30, OY + 24) == Where.OUTSIDE
    rng = np.random.default_rng(2)
    pts = np.column_stack([rng.uniform(OX - 5, OX + 65, 2000), rng.uniform(OY - 5, OY + 28, 2000)])
    many = b.contains_many(pts)
    one = np.array([b.contains(x, y) for x, y in pts])
    assert (many == one).all()
    ex = (pts[:, 0] > OX) & (pts[:, 0] < OX + 60) & (pts[:, 1] > OY) & (pts[:, 1] < OY + 23)
    hole = (
        (pts[:, 0] > OX + 20)
        & (pts[:, 0] < OX + 40)
        & (pts[:, 1] > OY + 9.2)
        & (pts[:, 1] < OY + 13.8)
    )
    assert (one == (ex & ~hole)).all()


def test_multipolygon_and_concave_boundary():
    # an L-shaped field plus a separate square, as a MultiPolygon
    L = [[0, 0], [10, 0], [10, 4], [4, 4], [4, 10], [0, 10], [0, 0]]
    sq = [[20, 0], [25, 0], [25, 5], [20, 5], [20, 0]]
    b = FieldBoundary({"type": "MultiPolygon", "coordinates": [[L], [sq]]})
    assert b.contains(2, 8) and b.contains(8, 2) and not b.contains(8, 8)
    assert b.contains(22, 2) and not b.contains(15, 2)


def test_distance_to_cell():
    job = trial_plot()
    loc = CellLocator(job.corners_utm)
    assert loc.distance_to_cell(0, OX + 2, OY + 1) == 0.0
    assert loc.distance_to_cell(0, OX - 0.5, OY + 1) == pytest.approx(0.5)


def test_empty_job_locator():
    loc = CellLocator([])
    assert loc.locate(1.0, 2.0) == -1
