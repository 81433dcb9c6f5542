"""Step-response and disturbance-rejection metrics, shared by tests and bench.

Times are found by linear interpolation between samples, so a 2 ms
simulation still resolves rise and settling times well below one sample.
All percentages are relative to the step amplitude |r1 - r0|.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass


@dataclass(frozen=True)
class StepMetrics:
    rise_10_90_s: float
    rise_0_90_s: float
    settling_2pct_s: float
    settling_5pct_s: float
    overshoot_pct: float
    steady_state_error_pct: float
    iae: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


@dataclass(frozen=True)
class DisturbanceMetrics:
    peak_deviation_pct: float
    peak_time_s: float
    recovery_2pct_s: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def _crossing(t: Sequence[float], x: Sequence[float], level: float, start: int = 0) -> float:
    """First time x rises through ``level`` (x normalised to rise from 0 to 1)."""
    for k in range(max(start, 1), len(x)):
        if x[k] >= level:
            if x[k - 1] >= level:
                return t[k - 1] if k - 1 >= start else t[k]
            frac = (level - x[k - 1]) / (x[k] - x[k - 1])
            return t[k - 1] + frac * (t[k] - t[k - 1])
    if start < len(x) and len(x) and x[start] >= level:
        return t[start]
    return math.nan


def settling_time(
    t: Sequence[float], y: Sequence[float], target: float, band: float, t0: float = 0.0
) -> float:
    """Time from ``t0`` after which |y - target| stays within ``band`` (absolute).

    NaN if the response is still outside the band at the last sample.
    """
    if abs(y[-1] - target) > band:
        return math.nan
    k = len(y) - 1
    while k > 0 and t[k - 1] >= t0 and abs(y[k - 1] - target) <= band:
        k -= 1
    if k == 0 or t[k - 1] < t0:
        return max(t[k] - t0, 0.0) if k > 0 else 0.0
    # y[k-1] is outside, y[k] inside: interpolate where it enters the band.
    a, b = y[k - 1] - target, y[k] - target
    edge = band if a > 0 else -band
    frac = (edge - a) / (b - a) if b != a else 1.0
    return t[k - 1] + frac * (t[k] - t[k - 1]) - t0


def step_metrics(
    t: Sequence[float],
    y: Sequence[float],
    r0: float,
    r1: float,
    t0: float = 0.0,
) -> StepMetrics:
    """Metrics of the response ``y`` to a setpoint step r0 -> r1 at time ``t0``.

    Rise, settling and overshoot are measured against the setpoint r1 (the
    tracking goal; equals the final value for a loop with integral action).
    Rise 10-90 % and 0-90 % are from t0; overshoot is the peak beyond r1 in
    the direction of the step; steady-state error is (r1 - y_end) as % of the
    step; IAE integrates |r1 - y| (trapezoid) from t0.
    """
    amp = r1 - r0
    if amp == 0:
        raise ValueError("step amplitude must be non-zero")
    start = next((k for k, tk in enumerate(t) if tk >= t0), len(t))
    tt = t[start:]
    x = [(yk - r0) / amp for yk in y[start:]]
    t10 = _crossing(tt, x, 0.1)
    t90 = _crossing(tt, x, 0.9)
    peak = max(x) if x else math.nan
    over = max(0.0, (peak - 1.0) * 100.0)
    iae = 0.0
    for k in range(1, len(tt)):
        iae += 0.5 * (abs(r1 - y[start + k]) + abs(r1 - y[start + k - 1])) * (tt[k] - tt[k - 1])
    return StepMetrics(
        rise_10_90_s=t90 - t10,
        rise_0_90_s=t90 - t0,
        settling_2pct_s=settling_time(tt, x, 1.0, 0.02, t0),
        settling_5pct_s=settling_time(tt, x, 1.0, 0.05, t0),
        overshoot_pct=over,
        steady_state_error_pct=(1.0 - x[-1]) * 100.0,
        iae=iae,
    )


def disturbance_metrics(
    t: Sequence[float],
    y: Sequence[float],
    setpoint: float,
    t_dist: float,
    scale: float,
) -> DisturbanceMetrics:
    """Peak deviation from ``setpoint`` after a disturbance at ``t_dist``.

    Peak deviation is in % of ``scale`` (the reference step amplitude);
    recovery is the time from ``t_dist`` until the output stays within 2 % of
    ``scale`` around the setpoint (NaN if it never does).
    """
    start = next((k for k, tk in enumerate(t) if tk >= t_dist), len(t))
    dev = [abs(yk - setpoint) for yk in y[start:]]
    if not dev:
        return DisturbanceMetrics(math.nan, math.nan, math.nan)
    kmax = max(range(len(dev)), key=dev.__getitem__)
    return DisturbanceMetrics(
        peak_deviation_pct=dev[kmax] / abs(scale) * 100.0,
        peak_time_s=t[start + kmax] - t_dist,
        recovery_2pct_s=settling_time(t[start:], y[start:], setpoint, 0.02 * abs(scale), t_dist),
    )
