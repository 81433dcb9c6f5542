"""Rates: a rate model (``ratemodels``, one class per model) applied to the cells, and what
the implement can meter.

Pure, vectorised functions over numpy arrays. Which rates an implement can
actually meter is checked separately (``check_meter_range``): a rate it cannot
meter is kept as computed and flagged per cell, never silently changed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from fieldrx_edge.metering import (
    Calibration,
    calibration_from_dict,
    meterable_rate_range_kg_ha,
    shaft_rpm_for_rate,
)

from fieldrx.agronomy.cells import FLAG_BITS
from fieldrx.agronomy.ratemodels.registry import rate_model


def model_rates(
    model: str, values: np.ndarray | None, params: dict[str, Any], n: int
) -> np.ndarray:
    """The rates of the model named ``model`` (``ratemodels``; its parameters are listed
    there with their units, defaults and papers). ``values`` is the model's per-cell
    input (soil N, NDVI; None for a model without one).

    NaN values propagate as NaN (no data); the caller applies its fallback.
    """
    return rate_model(model).rates(values, params, n)


# Metering range ---------------------------------------------------------------


class MeterRangeError(ValueError):
    """No rate fits the meter over the whole planned speed range."""


@dataclass(frozen=True)
class MeterCheck:
    """What the implement can meter (seed 001 eq. 1-3 via fieldrx_edge.metering)."""

    calibration: Calibration
    width_m: float
    speed_min_m_s: float
    speed_max_m_s: float

    @classmethod
    def from_kmh(
        cls,
        calibration: Calibration | dict[str, Any],
        width_m: float,
        speed_min_kmh: float,
        speed_max_kmh: float,
    ) -> MeterCheck:
        cal = calibration_from_dict(calibration) if isinstance(calibration, dict) else calibration
        if not 0 < speed_min_kmh <= speed_max_kmh:
            raise MeterRangeError(
                f"speed range must satisfy 0 < min <= max, "
                f"got {speed_min_kmh}..{speed_max_kmh} km/h"
            )
        if not width_m > 0:
            raise MeterRangeError(f"width_m must be > 0, got {width_m}")
        return cls(cal, float(width_m), speed_min_kmh / 3.6, speed_max_kmh / 3.6)

    def range_kg_ha(self) -> tuple[float, float]:
        """Rates meterable at every planned speed: (lowest, highest)."""
        return meterable_rate_range_kg_ha(
            self.calibration, self.width_m, self.speed_min_m_s, self.speed_max_m_s
        )

    def shaft_rpm(self, rate_kg_ha: float, speed_m_s: float) -> float:
        """Shaft speed for a rate at a speed: r = (6 Q L v + 404.4) / 237.2 (seed 001)."""
        return shaft_rpm_for_rate(self.calibration, rate_kg_ha, self.width_m, speed_m_s)


def check_meter_range(
    rate_kg_ha: np.ndarray, meter: MeterCheck | None
) -> tuple[np.ndarray, np.ndarray, tuple[float, float] | None]:
    """Flag every rate the implement cannot meter at the planned speeds; change none.

    A rate of exactly 0 means "meter off" and is always possible. A positive
    rate below the lowest meterable rate (shaft floor at the slowest planned
    speed, seed 001 eq. 1-3) is flagged ``below_meter_range``, one above the
    highest (shaft ceiling at the fastest speed) ``above_meter_range``. The
    rates are returned as computed: the prescription keeps what the model or
    the agronomist asked for, and the flags (with their count, area and cells
    in the summary) say where the machine will not deliver it. Returns
    (rates, flag bits, range or None).
    """
    r = np.asarray(rate_kg_ha, dtype=float).copy()
    flags = np.zeros(len(r), dtype=np.uint16)
    if meter is None:
        return r, flags, None
    lo, hi = meter.range_kg_ha()
    if lo > hi:
        raise MeterRangeError(
            f"no rate can be metered over the whole speed range "
            f"{meter.speed_min_m_s * 3.6:g}-{meter.speed_max_m_s * 3.6:g} km/h: the lowest "
            f"meterable rate at the slowest speed ({lo:.1f} kg/ha) exceeds the highest at the "
            f"fastest speed ({hi:.1f} kg/ha); narrow the speed range"
        )
    flags[(r > 0) & (r < lo)] |= FLAG_BITS["below_meter_range"]
    flags[r > hi] |= FLAG_BITS["above_meter_range"]
    return r, flags, (lo, hi)


def require_meterable(rate_kg_ha: float, meter: MeterCheck | None, what: str) -> None:
    """Refuse a rate typed by a person that the implement cannot meter at the planned speeds.

    An edit is a number the agronomist gives now, so it is answered now (422)
    rather than stored and flagged: the message names the limit, the speed it
    assumes and the shaft speed behind it (seed 001 eq. 1-3). 0 (meter off) is
    always accepted.
    """
    if meter is None or rate_kg_ha <= 0:
        return
    lo, hi = meter.range_kg_ha()
    cal = meter.calibration
    if rate_kg_ha < lo:
        raise MeterRangeError(
            f"{what}: {rate_kg_ha:g} kg/ha is below the lowest rate this machine can meter at "
            f"its slowest planned speed {meter.speed_min_m_s * 3.6:.3g} km/h: {lo:.1f} kg/ha "
            f"(shaft floor {cal.min_rpm:g} r/min, width {meter.width_m:g} m); use 0 (off), "
            f"a rate >= {lo:.1f} kg/ha, or a machine / speed range that meters it"
        )
    if rate_kg_ha > hi:
        raise MeterRangeError(
            f"{what}: {rate_kg_ha:g} kg/ha is above the highest rate this machine can meter at "
            f"its fastest planned speed {meter.speed_max_m_s * 3.6:.3g} km/h: {hi:.1f} kg/ha "
            f"(shaft ceiling {cal.max_rpm:g} r/min, width {meter.width_m:g} m); use a rate "
            f"<= {hi:.1f} kg/ha, or a machine / speed range that meters it"
        )
