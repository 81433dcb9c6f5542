"""Seeding rate by productivity: seeds/ha per cell from the crop's NDVI, linear between two
end points, in the prescription's unit (seeds/ha).

Where the crop grows better (higher NDVI of the previous crop or of the field's imagery),
more plants can be carried, so more seeds are sown; where it grows poorly, fewer. The end
points are the agronomist's: the defaults are a maize population range (60 000 to
90 000 seeds/ha), not a paper's. NDVI outside [low, high] is clamped to the end points.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from fieldrx.agronomy.ratemodels.ndvi import ndvi_linear_rate
from fieldrx.agronomy.ratemodels.registry import RATE_MODELS, Input, Param, RateModel

MAIZE_RANGE = "a maize population range (agronomist's to set)"
NDVI_LOW, SEEDS_AT_LOW = 0.3, 60_000.0
NDVI_HIGH, SEEDS_AT_HIGH = 0.8, 90_000.0


def seeds_by_ndvi(
    ndvi: np.ndarray, ndvi_low: float, seeds_low: float, ndvi_high: float, seeds_high: float
) -> np.ndarray:
    """seeds/ha = seeds_low + (clamp(ndvi) - low) / (high - low) * (seeds_high - seeds_low):
    the NDVI line seed 000 uses for kg/ha, here in seeds/ha (one home for the line)."""
    return ndvi_linear_rate(ndvi, ndvi_low, seeds_low, ndvi_high, seeds_high)


@RATE_MODELS.register
class SeedingByNdvi(RateModel):
    """More seeds where the crop grows better; rates in seeds/ha (``rates_in_unit``)."""

    name = "seeding_ndvi"
    label = "Seeding rate by NDVI (seeds/ha)"
    short_label = "Seeding by NDVI"
    zone_label = "Sample NDVI (seeding rate)"
    paper = "none: the agronomist's population range"
    input = Input("ndvi", "sample NDVI")
    rates_in_unit: ClassVar[bool] = True
    params = (
        Param("ndvi_low", "", NDVI_LOW, MAIZE_RANGE),
        Param("seeds_at_low", "seeds/ha", SEEDS_AT_LOW, MAIZE_RANGE),
        Param("ndvi_high", "", NDVI_HIGH, MAIZE_RANGE),
        Param("seeds_at_high", "seeds/ha", SEEDS_AT_HIGH, MAIZE_RANGE),
    )

    def compute(self, values: np.ndarray, p: dict[str, Any]) -> np.ndarray:
        return seeds_by_ndvi(
            values,
            self.take(p, "ndvi_low"),
            self.take(p, "seeds_at_low"),
            self.take(p, "ndvi_high"),
            self.take(p, "seeds_at_high"),
        )
