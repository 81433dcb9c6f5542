"""fieldrx_edge.asapplied: how long each record's metering lasted (issue 11 defect 2)."""

from __future__ import annotations

import numpy as np
from fieldrx_edge.asapplied import fix_periods, metered_mass_g


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
