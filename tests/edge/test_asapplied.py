"""fieldrx_edge.asapplied: how long each record's metering lasted."""

from __future__ import annotations

import numpy as np
from fieldrx_edge.asapplied import (
    Cells,
    driven_length,
    fix_periods,
    landed_mass,
    landing_segments,
    m1_g,
    metered_mass_g,
    theta_pct,
)
from fieldrx_edge.metering import LinearCalibration, TableCalibration, flow_g_min_many


def test_carried_fix_period_wins_over_record_spacing() -> None:
    t = 1_790_000_000.0 + np.arange(50) * 0.1
    squeezed = 1_790_000_000.0 + np.arange(50) * 0.01  # stamped 10x too close
    period = np.full(50, 0.1)
    flow = np.full(50, 20.0)  # g/s
    honest = metered_mass_g(flow, fix_periods(t, period)).sum()
    assert np.isclose(honest, 50 * 0.1 * 20.0)
    assert np.isclose(metered_mass_g(flow, fix_periods(squeezed, period)).sum(), honest)
    # without a carried period the spacing decides (format 1 records): 10x too low
    assert np.isclose(metered_mass_g(flow, fix_periods(squeezed)).sum(), honest / 10)


def test_records_without_period_use_the_gap_but_not_across_an_outage() -> None:
    t = np.array([0.0, 0.1, 0.2, 5.0, 5.1])
    dts = fix_periods(t, np.array([np.nan, np.nan, np.nan, np.nan, np.nan]), max_gap_s=2.0)
    np.testing.assert_allclose(dts, [0.1, 0.1, 0.0, 0.1, 0.1])
    assert len(fix_periods(np.zeros(0))) == 0
    assert fix_periods(np.array([3.0]), np.array([0.2]))[0] == 0.2


def test_missed_fixes_extend_a_record_but_jitter_does_not() -> None:
    t = np.array([0.0, 0.11, 0.19, 0.3, 1.3, 1.4, 9.0])
    p = np.full(7, 0.1)
    # jitter: the period; a missed-fix gap (1.0 s, the agent holds its rate): the gap;
    # an outage beyond max_gap_s: the record's own period
    np.testing.assert_allclose(
        fix_periods(t, p, max_gap_s=2.0), [0.1, 0.1, 0.1, 1.0, 0.1, 0.1, 0.1]
    )


# --- the kernel's geometry: one driven length, one landing split, eq. 17-18 ---


def _two_cells() -> tuple[Cells, np.ndarray]:
    # two 2 m x 5 m cells of one swath driving north; corners rear-right, front-right,
    # front-left, rear-left (the grid's order)
    corners = np.array([[1, 0, 1, 5, -1, 5, -1, 0], [1, 5, 1, 10, -1, 10, -1, 5]], dtype=float)
    return Cells.build(corners, [0, 0]), corners


def test_driven_length_is_the_centre_line_for_rectangles_and_clipped_for_shapes() -> None:
    cells, corners = _two_cells()
    np.testing.assert_allclose(driven_length(cells), [5.0, 5.0])
    # the second cell's real shape stops at y = 8 (a field edge): 3 m of its line
    shaped = Cells.build(corners, [0, 0], {1: [[1, 5, 1, 8, -1, 8, -1, 5]]})
    np.testing.assert_allclose(driven_length(shaped), [5.0, 3.0])
    # a cell with a hole across its middle (even-odd over both rings)
    holed = Cells.build(corners, [0, 0], {0: [[1, 0, 1, 5, -1, 5, -1, 0],
                                              [2, 1, 2, 2, -2, 2, -2, 1]]})  # fmt: skip
    np.testing.assert_allclose(driven_length(holed), [4.0, 5.0])


def test_landing_segment_is_split_by_length_and_own_cell_wins_overlaps() -> None:
    cells, corners = _two_cells()
    p0 = np.array([[0.0, 4.0], [0.0, 20.0]])
    p1 = np.array([[0.0, 6.0], [0.0, 21.0]])
    m2, out = landed_mass(cells, np.array([10.0, 3.0]), p0, p1)
    np.testing.assert_allclose(m2, [5.0, 5.0])
    assert np.isclose(out, 3.0)
    # overlapping cells: the own cell takes the overlap, else the lower index
    over = Cells.build(corners, [0, 1], {1: [[1, 3, 1, 10, -1, 10, -1, 3]]})
    seg = (np.array([[0.0, 3.5]]), np.array([[0.0, 4.5]]))
    np.testing.assert_allclose(landed_mass(over, np.array([1.0]), *seg)[0], [1.0, 0.0])
    own = np.array([1])
    np.testing.assert_allclose(landed_mass(over, np.array([1.0]), *seg, own)[0], [0.0, 1.0])
    # a zero-length segment is a point
    pt = np.array([[0.0, 7.0]])
    np.testing.assert_allclose(landed_mass(cells, np.array([2.0]), pt, pt)[0], [0.0, 2.0])


def test_landing_is_lagged_and_moved_forward_eq_16() -> None:
    t = np.arange(0.0, 10.0, 0.1)
    x = np.zeros_like(t)
    y = 2.0 * t  # 2 m/s north
    p0, p1, known = landing_segments(t, np.full_like(t, 0.1), t, x, y, np.zeros_like(t), 1.5, 0.7)
    np.testing.assert_allclose(p0[10], [0.0, 2.0 * (1.0 + 1.5) + 0.7])
    np.testing.assert_allclose(p1[10], [0.0, 2.0 * (1.1 + 1.5) + 0.7])
    assert known[:85].all() and not known[-1]


def test_m1_theta_and_vectorised_flow_match_the_scalar_calibration() -> None:
    assert np.isclose(m1_g(np.array([300.0]), 2.3, np.array([5.0]))[0], 300 * 2.3 * 5 / 10)
    np.testing.assert_allclose(theta_pct(np.array([100.0, 0.0]), np.array([95.0, 3.0])),
                               [95.0, np.nan])  # fmt: skip
    for cal in (LinearCalibration(), TableCalibration(rpm=(5.0, 20.0, 40.0),
                                                      g_per_rev=(10.0, 12.0, 13.0))):  # fmt: skip
        r = np.array([-1.0, 0.0, 1.0, 3.0, 12.5, 30.0, 55.0, 90.0])
        want = [max(0.0, cal.flow_g_min(v)) if v > 0 else 0.0 for v in r]
        np.testing.assert_allclose(flow_g_min_many(cal, r), want)


def test_nothing_counts_outside_the_field() -> None:
    # the field ends at y = 8 and has a hole y 1..2: a rectangle reaching past the edge
    # (a plan's edge cell may keep its rectangle) is driven, and receives, only inside
    _, corners = _two_cells()
    field = [[[-5, 0], [5, 0], [5, 8], [-5, 8]], [[-5, 1], [5, 1], [5, 2], [-5, 2]]]
    cells = Cells.build(corners, [0, 0], None, field)
    np.testing.assert_allclose(driven_length(cells), [4.0, 3.0])
    m2, out = landed_mass(cells, np.array([10.0]), np.array([[0.0, 7.0]]), np.array([[0.0, 9.0]]))
    np.testing.assert_allclose(m2, [0.0, 5.0])
    assert np.isclose(out, 5.0)
