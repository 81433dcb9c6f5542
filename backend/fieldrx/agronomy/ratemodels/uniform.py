"""Uniform rate: the same kg/ha everywhere, the baseline variable-rate is compared with."""

from __future__ import annotations

from typing import Any

import numpy as np

from fieldrx.agronomy.ratemodels.registry import RATE_MODELS, Param, RateModel, RateModelError


def uniform_rate(n_cells: int, rate_kg_ha: float) -> np.ndarray:
    """The same rate everywhere (the baseline variable-rate is compared with)."""
    if not np.isfinite(rate_kg_ha) or rate_kg_ha < 0:
        raise RateModelError(f"uniform rate_kg_ha must be >= 0, got {rate_kg_ha!r}")
    return np.full(int(n_cells), float(rate_kg_ha))


@RATE_MODELS.register
class Uniform(RateModel):
    """One rate for every cell; no per-cell input, so no samples and no cell geometry."""

    name = "uniform"
    aliases = ("constant",)
    label = "Uniform rate"
    short_label = "Uniform rate"
    paper = "none: the agronomist's rate"
    params = (Param("rate_kg_ha", "kg/ha", None, "the agronomist", ("rate",)),)

    def compute_uniform(self, p: dict[str, Any], n: int) -> np.ndarray:
        return uniform_rate(n, float(p.pop("rate_kg_ha")))
