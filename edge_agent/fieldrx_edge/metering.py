"""Rate <-> metering shaft speed calibration.

The one place where a prescription rate (kg/ha) becomes a shaft speed (r/min)
and back. The server uses it to check that a rate can be metered at the planned
speeds; the edge agent uses it at every GNSS fix.

Seed 001 eq. 1-3 (centrifugal disc metering device):

    q0 = 237.2 * r - 404.4          [g/min], 30 <= r <= 130 r/min    (eq. 1)
    Q  = q0 / (6 * L * v)           [kg/ha], L width m, v speed m/s   (eq. 2-3)

The factor 6 is exact: 1 g/min = 0.06 kg/h and 1 m^2/s = 0.36 ha/h, so
Q = 0.06 q0 / (0.36 L v) = q0 / (6 L v).

Seed 000 (fluted-roller meter) discharges a mass per revolution that depends
on the shaft speed (its Fig. 9), so it needs a table calibration:
flow = g_per_rev(r) * r.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from typing import Literal, Protocol

import numpy as np


def rate_to_flow_g_min(rate_kg_ha: float, width_m: float, speed_m_s: float) -> float:
    """Mass flow the meter must deliver for a rate at a speed (seed 001 eq. 2 inverted)."""
    return 6.0 * rate_kg_ha * width_m * speed_m_s


def flow_to_rate_kg_ha(flow_g_min: float, width_m: float, speed_m_s: float) -> float:
    """Rate that a mass flow gives at a speed (seed 001 eq. 2); 0 when standing still."""
    if speed_m_s <= 0.0 or width_m <= 0.0:
        return 0.0
    return flow_g_min / (6.0 * width_m * speed_m_s)


class Calibration(Protocol):
    """A meter's flow as a function of shaft speed, with its usable speed range.

    The range is read-only (properties), so frozen dataclasses satisfy the protocol."""

    @property
    def min_rpm(self) -> float: ...

    @property
    def max_rpm(self) -> float: ...

    def flow_g_min(self, shaft_rpm: float) -> float: ...

    def shaft_rpm(self, flow_g_min: float) -> float: ...


@dataclass(frozen=True)
class LinearCalibration:
    """Seed 001 eq. 1: q0 = slope * r + intercept, valid for min_rpm <= r <= max_rpm."""

    slope_g_min_per_rpm: float = 237.2
    intercept_g_min: float = -404.4
    min_rpm: float = 30.0
    max_rpm: float = 130.0
    kind: Literal["linear"] = "linear"

    def flow_g_min(self, shaft_rpm: float) -> float:
        return self.slope_g_min_per_rpm * shaft_rpm + self.intercept_g_min

    def shaft_rpm(self, flow_g_min: float) -> float:
        """Shaft speed for a flow (eq. 1 inverted): r = (q0 + 404.4) / 237.2."""
        return (flow_g_min - self.intercept_g_min) / self.slope_g_min_per_rpm

    def to_dict(self) -> dict:
        return {
            "kind": "linear",
            "slope_g_min_per_rpm": self.slope_g_min_per_rpm,
            "intercept_g_min": self.intercept_g_min,
            "min_rpm": self.min_rpm,
            "max_rpm": self.max_rpm,
        }


@dataclass(frozen=True)
class TableCalibration:
    """Seed 000: discharge per revolution measured at several shaft speeds (Fig. 9).

    flow(r) = g_per_rev(r) * r with g_per_rev linearly interpolated between the
    measured points and held constant beyond them. flow(r) must increase with r
    so that it can be inverted; the constructor checks this.
    """

    rpm: tuple[float, ...]
    g_per_rev: tuple[float, ...]
    min_rpm: float = 6.0
    max_rpm: float = 40.0
    kind: Literal["table"] = "table"
    _flows: tuple[float, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if len(self.rpm) != len(self.g_per_rev) or len(self.rpm) < 2:
            raise ValueError("table calibration needs at least two (rpm, g_per_rev) points")
        if any(b <= a for a, b in zip(self.rpm, self.rpm[1:], strict=False)):
            raise ValueError("table calibration rpm values must be strictly increasing")
        flows = tuple(g * r for g, r in zip(self.g_per_rev, self.rpm, strict=True))
        if any(b <= a for a, b in zip(flows, flows[1:], strict=False)):
            raise ValueError("table calibration flow (g_per_rev * rpm) must increase with rpm")
        object.__setattr__(self, "_flows", flows)

    def _g_per_rev_at(self, shaft_rpm: float) -> float:
        rpm, gpr = self.rpm, self.g_per_rev
        if shaft_rpm <= rpm[0]:
            return gpr[0]
        if shaft_rpm >= rpm[-1]:
            return gpr[-1]
        i = bisect.bisect_right(rpm, shaft_rpm)
        t = (shaft_rpm - rpm[i - 1]) / (rpm[i] - rpm[i - 1])
        return gpr[i - 1] + t * (gpr[i] - gpr[i - 1])

    def flow_g_min(self, shaft_rpm: float) -> float:
        return self._g_per_rev_at(shaft_rpm) * shaft_rpm

    def shaft_rpm(self, flow_g_min: float) -> float:
        """Invert flow(r) exactly on each linear piece of g_per_rev (a quadratic in r)."""
        rpm, gpr, flows = self.rpm, self.g_per_rev, self._flows
        if flow_g_min <= flows[0]:
            return flow_g_min / gpr[0]
        if flow_g_min >= flows[-1]:
            return flow_g_min / gpr[-1]
        i = bisect.bisect_right(flows, flow_g_min)
        r0, r1, g0, g1 = rpm[i - 1], rpm[i], gpr[i - 1], gpr[i]
        a = (g1 - g0) / (r1 - r0)  # g(r) = g0 + a (r - r0); flow = g(r) * r
        b = g0 - a * r0
        if abs(a) < 1e-12:
            return flow_g_min / b
        disc = b * b + 4.0 * a * flow_g_min
        return (-b + disc**0.5) / (2.0 * a)

    def to_dict(self) -> dict:
        return {
            "kind": "table",
            "rpm": list(self.rpm),
            "g_per_rev": list(self.g_per_rev),
            "min_rpm": self.min_rpm,
            "max_rpm": self.max_rpm,
        }


SEED001_CALIBRATION = LinearCalibration()


def calibration_from_dict(data: dict) -> LinearCalibration | TableCalibration:
    """Build a calibration from its JSON form (job package, machine record)."""
    kind = data.get("kind", "linear")
    if kind == "linear":
        return LinearCalibration(
            slope_g_min_per_rpm=float(data.get("slope_g_min_per_rpm", 237.2)),
            intercept_g_min=float(data.get("intercept_g_min", -404.4)),
            min_rpm=float(data.get("min_rpm", 30.0)),
            max_rpm=float(data.get("max_rpm", 130.0)),
        )
    if kind == "table":
        return TableCalibration(
            rpm=tuple(float(v) for v in data["rpm"]),
            g_per_rev=tuple(float(v) for v in data["g_per_rev"]),
            min_rpm=float(data.get("min_rpm", 6.0)),
            max_rpm=float(data.get("max_rpm", 40.0)),
        )
    raise ValueError(f"unknown calibration kind {kind!r} (expected 'linear' or 'table')")


def shaft_rpm_for_rate(
    cal: Calibration, rate_kg_ha: float, width_m: float, speed_m_s: float
) -> float:
    """Target shaft speed for a rate at a speed: r = (6 Q L v + 404.4) / 237.2 for seed 001.

    Returns 0 for a zero rate or a standing machine (nothing to meter); the
    caller checks the result against [min_rpm, max_rpm] and raises its alarm.
    """
    if rate_kg_ha <= 0.0 or speed_m_s <= 0.0:
        return 0.0
    return cal.shaft_rpm(rate_to_flow_g_min(rate_kg_ha, width_m, speed_m_s))


def rate_for_shaft_rpm(
    cal: Calibration, shaft_rpm: float, width_m: float, speed_m_s: float
) -> float:
    """Rate actually applied at a shaft speed (0 below the meter's zero-flow speed)."""
    if shaft_rpm <= 0.0:
        return 0.0
    return max(0.0, flow_to_rate_kg_ha(cal.flow_g_min(shaft_rpm), width_m, speed_m_s))


def rate_range_kg_ha(cal: Calibration, width_m: float, speed_m_s: float) -> tuple[float, float]:
    """Lowest and highest rate the meter can hold at one speed (its calibrated rpm range)."""
    return (
        flow_to_rate_kg_ha(cal.flow_g_min(cal.min_rpm), width_m, speed_m_s),
        flow_to_rate_kg_ha(cal.flow_g_min(cal.max_rpm), width_m, speed_m_s),
    )


def meterable_rate_range_kg_ha(
    cal: Calibration, width_m: float, speed_min_m_s: float, speed_max_m_s: float
) -> tuple[float, float]:
    """Rates the meter can hold at every speed of a planned speed range.

    The floor (min_rpm) is most restrictive at the slowest speed, the ceiling
    (max_rpm) at the fastest. If lo > hi no single rate fits the whole range.
    """
    lo = rate_range_kg_ha(cal, width_m, speed_min_m_s)[0]
    hi = rate_range_kg_ha(cal, width_m, speed_max_m_s)[1]
    return lo, hi


def flow_g_min_many(cal: Calibration, shaft_rpm: np.ndarray) -> np.ndarray:
    """Vectorised ``cal.flow_g_min`` for an array of shaft speeds (g/min, >= 0; 0 at rest).

    Seed 001 eq. 1 for a linear calibration, g_per_rev interpolated and held beyond the
    table for a table calibration (seed 000), exactly as the scalar methods compute it.
    """
    r = np.asarray(shaft_rpm, dtype=float)
    if isinstance(cal, TableCalibration):
        q = np.interp(r, np.asarray(cal.rpm), np.asarray(cal.g_per_rev)) * r
    elif isinstance(cal, LinearCalibration):
        q = cal.slope_g_min_per_rpm * r + cal.intercept_g_min
    else:  # any other calibration: its own scalar method, element by element
        q = np.vectorize(cal.flow_g_min, otypes=[float])(r)
    return np.where(r > 0, np.maximum(q, 0.0), 0.0)
