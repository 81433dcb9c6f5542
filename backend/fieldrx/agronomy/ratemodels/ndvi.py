"""NDVI curve (seed 000): crop NDVI per cell -> kg/ha of product, linear between two
end points (corn topdressing)."""

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

SEED_000 = "seed 000 NDVI curve"
# Seed 000 NDVI -> rate end points (corn topdressing).
NDVI_LOW, RATE_AT_NDVI_LOW = 0.24, 375.0
NDVI_HIGH, RATE_AT_NDVI_HIGH = 0.65, 180.0


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


@RATE_MODELS.register
class NdviCurve(RateModel):
    """Seed 000's linear NDVI -> rate curve; its end points are what the map's
    plausibility check counts cells at."""

    name = "ndvi"
    aliases = ("ndvi_linear",)
    label = "NDVI (linear, seed 000)"
    short_label = "NDVI curve"
    zone_label = "Sample NDVI (NDVI rate)"
    paper = SEED_000
    input = Input("ndvi", "sample NDVI")
    params = (
        Param("ndvi_low", "", NDVI_LOW, SEED_000),
        Param("rate_at_low_kg_ha", "kg/ha", RATE_AT_NDVI_LOW, SEED_000),
        Param("ndvi_high", "", NDVI_HIGH, SEED_000),
        Param("rate_at_high_kg_ha", "kg/ha", RATE_AT_NDVI_HIGH, SEED_000),
    )

    def compute(self, values: np.ndarray, p: dict[str, Any]) -> np.ndarray:
        return ndvi_linear_rate(
            values,
            self.take(p, "ndvi_low"),
            self.take(p, "rate_at_low_kg_ha"),
            self.take(p, "ndvi_high"),
            self.take(p, "rate_at_high_kg_ha"),
        )

    def curve_kg_ha(self, params: dict[str, Any]) -> tuple[float, float] | None:
        p = dict(params)
        return self.take(p, "rate_at_low_kg_ha"), self.take(p, "rate_at_high_kg_ha")
