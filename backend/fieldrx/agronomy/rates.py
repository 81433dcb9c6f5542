"""Rate models: soil or crop data per cell -> fertilizer rate in kg/ha of product.

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

# Seed 001 eq. 19-21 parameters (winter oilseed rape).
DEFAULT_E_KG_PER_100KG = 5.8  # kg N taken up per 100 kg of yield
DEFAULT_K_UTILISATION = 0.342  # fertilizer N utilisation
# Eq. 20 soil-nutrient correction d = (a + b / n) / 100, fitted in seed 001 for oilseed rape;
# other crops' values are in agronomy.crops.
D_INTERCEPT_PCT = 5.57
D_SLOPE_PCT_MG_KG = 3226.05
# mg/kg in the 0-20 cm layer -> kg/ha (2,250,000 kg of soil per ha), seed 001 eq. 19
SOIL_KG_HA_PER_MG_KG = 2.25
# Seed 000 NDVI -> rate end points (corn topdressing).
NDVI_LOW, RATE_AT_NDVI_LOW = 0.24, 375.0
NDVI_HIGH, RATE_AT_NDVI_HIGH = 0.65, 180.0

MODELS = ("nutrient_balance", "ndvi", "uniform")


class RateModelError(ValueError):
    """Bad model name or parameter; the message names the parameter."""


def soil_correction_coefficient(
    n_mg_kg: np.ndarray | float,
    intercept_pct: float = D_INTERCEPT_PCT,
    slope_pct_mg_kg: float = D_SLOPE_PCT_MG_KG,
) -> np.ndarray:
    """Seed 001 eq. 20: d = (5.57 + 3226.05 / n) / 100, clamped to [0, 1].

    ``intercept_pct`` / ``slope_pct_mg_kg`` are a and b of d = (a + b / n) / 100 (the
    seed's values for oilseed rape; another crop's from ``agronomy.crops``).

    Erratum (docs/science.md): d exceeds 100 % for n < 34.2 mg/kg; a soil cannot
    supply more than all of its available N, so d is clamped to 1. n <= 0 gives
    d = 1 (the limit), never a division error.
    """
    n = np.asarray(n_mg_kg, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        d = (intercept_pct + slope_pct_mg_kg / n) / 100.0
    return np.where(n > 0, np.clip(d, 0.0, 1.0), 1.0)


def nutrient_balance_rate(
    n_mg_kg: np.ndarray | float,
    target_yield_kg_ha: float,
    n_fraction: float,
    e_kg_per_100kg: float = DEFAULT_E_KG_PER_100KG,
    k_utilisation: float = DEFAULT_K_UTILISATION,
    soil_d: tuple[float, float] = (D_INTERCEPT_PCT, D_SLOPE_PCT_MG_KG),
) -> np.ndarray:
    """Seed 001 eq. 19-21 (corrected in docs/science.md): product rate in kg/ha.

        F = (e * M / 100 - 2.25 * d * n) / (k * x),  d = min(1, (5.57 + 3226.05/n)/100)

    M target yield kg/ha, e kg N per 100 kg yield, n alkali-hydrolysable N mg/kg
    (2.25 converts mg/kg in the 0-20 cm layer to kg/ha), k fertilizer N
    utilisation, x N mass fraction of the product. Erratum: eq. 19 as printed
    omits the /100 on e*M. A negative F means the soil already supplies enough
    N, so the rate is 0 (use ``nutrient_balance_raw`` to see the sign).
    Worked example: M 2500, n 100, x 0.25 -> 700.4 kg/ha.
    """
    return np.asarray(
        np.maximum(
            0.0,
            nutrient_balance_raw(
                n_mg_kg, target_yield_kg_ha, n_fraction, e_kg_per_100kg, k_utilisation, soil_d
            ),
        )
    )


def nutrient_balance_raw(
    n_mg_kg: np.ndarray | float,
    target_yield_kg_ha: float,
    n_fraction: float,
    e_kg_per_100kg: float = DEFAULT_E_KG_PER_100KG,
    k_utilisation: float = DEFAULT_K_UTILISATION,
    soil_d: tuple[float, float] = (D_INTERCEPT_PCT, D_SLOPE_PCT_MG_KG),
) -> np.ndarray:
    """Seed 001 eq. 19-21 before the F >= 0 clamp (negative = N surplus); ``soil_d`` is
    eq. 20's (a, b)."""
    if not target_yield_kg_ha > 0:
        raise RateModelError(f"target_yield_kg_ha must be > 0, got {target_yield_kg_ha!r}")
    if not 0 < n_fraction <= 1:
        raise RateModelError(f"n_fraction must be in (0, 1], got {n_fraction!r}")
    if not 0 < k_utilisation <= 1:
        raise RateModelError(f"k_utilisation must be in (0, 1], got {k_utilisation!r}")
    if not e_kg_per_100kg > 0:
        raise RateModelError(f"e_kg_per_100kg must be > 0, got {e_kg_per_100kg!r}")
    if not (np.isfinite(soil_d[0]) and np.isfinite(soil_d[1])) or soil_d[1] < 0:
        raise RateModelError(
            f"d_intercept_pct / d_slope_pct_mg_kg must be finite and the slope >= 0, got {soil_d}"
        )
    n = np.asarray(n_mg_kg, dtype=float)
    d = soil_correction_coefficient(n, *soil_d)
    soil_n = SOIL_KG_HA_PER_MG_KG * d * np.maximum(n, 0.0)
    return np.asarray(
        (e_kg_per_100kg * target_yield_kg_ha / 100.0 - soil_n) / (k_utilisation * n_fraction)
    )


def ndvi_linear_rate(
    ndvi: np.ndarray | float,
    ndvi_low: float = NDVI_LOW,
    rate_at_low_kg_ha: float = RATE_AT_NDVI_LOW,
    ndvi_high: float = NDVI_HIGH,
    rate_at_high_kg_ha: float = RATE_AT_NDVI_HIGH,
) -> np.ndarray:
    """Seed 000: NDVI 0.24 -> 375 kg/ha, 0.65 -> 180 kg/ha, linear in between.

    Less N where the crop is greener. NDVI outside [low, high] is clamped to the
    end points, so the rate never leaves [180, 375] with the default end points.
    """
    if not ndvi_high > ndvi_low:
        raise RateModelError(f"ndvi_high ({ndvi_high}) must exceed ndvi_low ({ndvi_low})")
    if rate_at_low_kg_ha < 0 or rate_at_high_kg_ha < 0:
        raise RateModelError("NDVI end-point rates must not be negative")
    v = np.clip(np.asarray(ndvi, dtype=float), ndvi_low, ndvi_high)
    t = (v - ndvi_low) / (ndvi_high - ndvi_low)
    return np.asarray(rate_at_low_kg_ha + t * (rate_at_high_kg_ha - rate_at_low_kg_ha))


def uniform_rate(n_cells: int, rate_kg_ha: float) -> np.ndarray:
    """The same rate everywhere (the baseline variable-rate is compared with)."""
    if not np.isfinite(rate_kg_ha) or rate_kg_ha < 0:
        raise RateModelError(f"uniform rate_kg_ha must be >= 0, got {rate_kg_ha!r}")
    return np.full(int(n_cells), float(rate_kg_ha))


def model_rates(
    model: str, values: np.ndarray | None, params: dict[str, Any], n: int
) -> np.ndarray:
    """Dispatch by model name. ``values`` is n_mg_kg (nutrient_balance) or NDVI.

    NaN values propagate as NaN (no data); the caller applies its fallback.
    nutrient_balance params: target_yield_kg_ha, n_fraction, e_kg_per_100kg, k_utilisation,
    d_intercept_pct, d_slope_pct_mg_kg (eq. 20's a and b).
    ndvi params: ndvi_low, rate_at_low_kg_ha, ndvi_high, rate_at_high_kg_ha.
    uniform params: rate_kg_ha.
    """
    p = dict(params)
    try:
        if model == "uniform":
            out = uniform_rate(n, float(p.pop("rate_kg_ha")))
            if p:
                raise RateModelError(f"model 'uniform': unknown parameters {sorted(p)}")
            return out
        if values is None:
            raise RateModelError(f"model {model!r} needs per-cell values (soil N or NDVI)")
        v = np.asarray(values, dtype=float)
        if model == "nutrient_balance":
            out = nutrient_balance_rate(
                v,
                float(p.pop("target_yield_kg_ha")),
                float(p.pop("n_fraction")),
                float(p.pop("e_kg_per_100kg", DEFAULT_E_KG_PER_100KG)),
                float(p.pop("k_utilisation", DEFAULT_K_UTILISATION)),
                (
                    float(p.pop("d_intercept_pct", D_INTERCEPT_PCT)),
                    float(p.pop("d_slope_pct_mg_kg", D_SLOPE_PCT_MG_KG)),
                ),
            )
        elif model == "ndvi":
            out = ndvi_linear_rate(
                v,
                float(p.pop("ndvi_low", NDVI_LOW)),
                float(p.pop("rate_at_low_kg_ha", RATE_AT_NDVI_LOW)),
                float(p.pop("ndvi_high", NDVI_HIGH)),
                float(p.pop("rate_at_high_kg_ha", RATE_AT_NDVI_HIGH)),
            )
        else:
            raise RateModelError(f"unknown model {model!r} (expected one of {list(MODELS)})")
    except KeyError as exc:
        raise RateModelError(f"model {model!r} needs parameter {exc.args[0]!r}") from None
    except (TypeError, ValueError) as exc:
        if isinstance(exc, RateModelError):
            raise
        raise RateModelError(f"model {model!r}: bad parameter value ({exc})") from None
    if p:
        raise RateModelError(f"model {model!r}: unknown parameters {sorted(p)}")
    return np.where(np.isnan(v), np.nan, out)


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
