"""Sowing depth (seed 002): calibration, the loop on the corrected plant, GB/T 20865 metrics."""

from __future__ import annotations

import statistics

import pytest
from fieldrx_edge.depth import (
    DepthLoop,
    DepthSensorCalibration,
    depth_quality,
    qualified_band_mm,
)
from fieldrx_edge.plants import seed002_depth


def test_calibration_eq13_and_erratum() -> None:
    cal = DepthSensorCalibration()
    assert cal.depth_mm(2628.0) == pytest.approx(99.53)  # not 0..60 mm (erratum)
    assert cal.depth_mm(4356.0) == pytest.approx(-12.79)
    assert cal.depth_mm(cal.signal_mv(30.0)) == pytest.approx(30.0)
    assert not cal.is_valid(99.5) and cal.is_valid(30.0)
    other = DepthSensorCalibration(slope_mm_per_mv=-0.05, intercept_mm=200.0)
    assert other.depth_mm(3000.0) == pytest.approx(50.0)


def test_quality_metrics_computed_from_data() -> None:
    d = [30.0, 31.0, 29.0, 45.0, 19.0, 30.5]
    q = depth_quality(d, 30.0)
    assert q.n == 6
    assert q.mean_mm == pytest.approx(statistics.fmean(d))
    assert q.pass_rate_pct == pytest.approx(100 * 4 / 6)  # 45 and 19 are outside 20..40
    assert q.std_mm == pytest.approx(statistics.stdev(d))
    assert q.cv_pct == pytest.approx(100 * q.std_mm / q.mean_mm)
    assert qualified_band_mm(30.0) == (20.0, 40.0)
    assert qualified_band_mm(25.0) == (20.0, 30.0)
    # The paper's Table 3 pair (std 0.18 mm, CV 2.93 %) implies a mean of 6.1 mm, not 30.13 mm.
    assert 0.18 / 0.0293 == pytest.approx(6.14, abs=0.01)
    with pytest.raises(ValueError):
        depth_quality([30.0])


@pytest.mark.slow
def test_depth_loop_reaches_target_and_holds_on_sensor_fault() -> None:
    plant = seed002_depth(1e-3)
    plant.reset(25.0)
    loop = DepthLoop(target_mm=30.0)
    cal = loop.calibration
    depths = []
    for _ in range(4000):
        u = loop.step(cal.signal_mv(plant.output))
        depths.append(plant.step(u))
    assert depths[-1] == pytest.approx(30.0, abs=0.05)
    q = depth_quality(depths[-1000:], 30.0)
    assert q.pass_rate_pct == 100.0 and q.std_mm < 0.05
    held = loop.controller.output
    assert loop.step(cal.signal_mv(99.0)) == held  # out of range: hold, count
    assert loop.faults == 1
