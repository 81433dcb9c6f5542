"""Prescription cells: the one cell type with the agronomy's per-cell flags.

``CellTable`` is :class:`fieldrx.geo.cells.Cells` (one in-memory cell type for the
grid, the store, rate models, interpolation and every export); this module adds
what only agronomy knows: the meaning of the per-cell flag bits.
"""

from __future__ import annotations

import numpy as np

from fieldrx.geo.cells import Cells

CellTable = Cells  # the rate models' name for the one cell type

# Per-cell flags are a bit mask so that they stay one uint16 column; names are
# what the API, tiles and exports show.
FLAG_BITS: dict[str, int] = {
    "no_data": 1,  # interpolation had no sample for the cell: fallback rate used
    "below_meter_range": 2,  # rate below what the implement can meter (kept as asked)
    "above_meter_range": 4,  # rate above what the implement can meter (kept as asked)
    "manual": 8,  # rate set by a per-cell edit
    "zone": 16,  # rate set by zone painting
    "clamped_min": 32,  # model rate raised to the agronomist's minimum (reported)
    "clamped_max": 64,  # model rate lowered to the agronomist's maximum (reported)
    # kg of a nutrient per ha above the crop's / organisation's ceiling (agronomy.plausibility)
    "above_nutrient_ceiling": 128,
    # at a rate curve's cap or floor when more of the field than allowed is (plausibility)
    "at_curve_limit": 256,
}


def flag_names(mask: int) -> list[str]:
    """Names of the flags set in one cell's mask, in FLAG_BITS order."""
    return [name for name, bit in FLAG_BITS.items() if int(mask) & bit]


def flag_strings(flags: np.ndarray) -> list[str]:
    """Comma-separated flag names per cell ("" when none), for tables and tiles."""
    cache: dict[int, str] = {}
    out: list[str] = []
    for m in np.asarray(flags, dtype=np.int64).tolist():
        s = cache.get(m)
        if s is None:
            s = cache[m] = ",".join(flag_names(m))
        out.append(s)
    return out
