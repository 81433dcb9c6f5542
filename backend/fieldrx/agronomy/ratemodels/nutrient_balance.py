"""Nutrient balance (seed 001 eq. 19-21): soil N per cell -> kg/ha of product.

The crop's N demand for a target yield minus what the soil supplies, divided by how much
of the fertiliser's N the crop takes up and the product's N fraction.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fieldrx.agronomy.ratemodels.registry import (
    RATE_MODELS,
    Input,
    Param,
    RateModel,
    RateModelError,
)

SEED_001 = "seed 001 eq. 19-21 (winter oilseed rape)"
# Seed 001 eq. 19-21 parameters (winter oilseed rape).
DEFAULT_E_KG_PER_100KG = 5.8  # kg N taken up per 100 kg of yield
DEFAULT_K_UTILISATION = 0.342  # fertilizer N utilisation
# Eq. 20 soil-nutrient correction d = (a + b / n) / 100, fitted in seed 001 for oilseed rape;
# other crops' values are in agronomy.crops.
D_INTERCEPT_PCT = 5.57
D_SLOPE_PCT_MG_KG = 3226.05
# mg/kg in the 0-20 cm layer -> kg/ha (2,250,000 kg of soil per ha), seed 001 eq. 19
SOIL_KG_HA_PER_MG_KG = 2.25


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


@RATE_MODELS.register
class NutrientBalance(RateModel):
    """Seed 001 eq. 19-21 from alkali-hydrolysable soil N; the crop and the product fill
    the parameters a request leaves out."""

    name = "nutrient_balance"
    label = "Nutrient balance (soil N, seed 001)"
    short_label = "Nutrient balance (soil N)"
    zone_label = "Soil N (nutrient balance rate)"
    paper = SEED_001
    input = Input("n_mg_kg", "soil n_mg_kg")
    crop_defaults = True
    params = (
        Param(
            "target_yield_kg_ha",
            "kg/ha",
            None,
            "the crop's reference yield (agronomy.crops)",
            ("M", "target_yield"),
        ),
        Param(
            "n_fraction", "fraction", None, "the product's N % / 100", ("x", "nutrient_fraction")
        ),
        Param(
            "e_kg_per_100kg",
            "kg N / 100 kg yield",
            DEFAULT_E_KG_PER_100KG,
            SEED_001,
            ("e", "uptake_kg_per_100kg"),
        ),
        Param("k_utilisation", "fraction", DEFAULT_K_UTILISATION, SEED_001, ("k", "utilisation")),
        Param("d_intercept_pct", "%", D_INTERCEPT_PCT, "seed 001 eq. 20"),
        Param("d_slope_pct_mg_kg", "% mg/kg", D_SLOPE_PCT_MG_KG, "seed 001 eq. 20"),
    )

    def compute(self, values: np.ndarray, p: dict[str, Any]) -> np.ndarray:
        return nutrient_balance_rate(
            values,
            float(p.pop("target_yield_kg_ha")),
            float(p.pop("n_fraction")),
            self.take(p, "e_kg_per_100kg"),
            self.take(p, "k_utilisation"),
            (self.take(p, "d_intercept_pct"), self.take(p, "d_slope_pct_mg_kg")),
        )
