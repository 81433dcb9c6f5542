"""Plausibility checks of a rate map before it leaves the office: per-nutrient ceilings
(kg N, P2O5, K2O per ha) and the share of a field at a rate curve's end points.

Pure: rates, the product's nutrient fractions and the ceilings in; flag bits and a report
(count, area, where) out. Rates are never changed: like the meter-range flags, a cell above
a ceiling is flagged and counted, and a job with such cells is sent only on confirmation.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from fieldrx.agronomy.cells import FLAG_BITS
from fieldrx.agronomy.crops import NUTRIENTS, Crop

# A rate curve (seed 000's NDVI line) that puts more than this share of the field at
# one of its end points is probably fed the wrong scale of input (another sensor's NDVI,
# a scene's reflectance offset): the sender confirms it. Organisations may change it.
DEFAULT_CURVE_SHARE_MAX = 0.25
MAX_LISTED = 1000


def product_fractions(
    product: Mapping[str, Any] | None, params: Mapping[str, Any]
) -> dict[str, float]:
    """Nutrient mass fractions of what is spread: the catalogue product's analysis, else
    the nutrient-balance model's N fraction x (seed 001 eq. 19); empty when unknown."""
    if product is not None:
        cols = {"N": "n_pct", "P2O5": "p2o5_pct", "K2O": "k2o_pct"}
        return {n: float(product.get(c) or 0.0) / 100.0 for n, c in cols.items()}
    x = params.get("n_fraction")
    return {"N": float(x)} if x is not None else {}


def resolve_ceilings(crop: Crop | None, org: Mapping[str, Any] | None) -> dict[str, dict[str, Any]]:
    """Each nutrient's ceiling in kg/ha and its source: the organisation's value for this
    crop (or for every crop, key "*") over the crop's published default."""
    org = org or {}
    mine = {**(org.get("*") or {}), **((org.get(crop.key) or {}) if crop else {})}
    out: dict[str, dict[str, Any]] = {}
    for n in NUTRIENTS:
        if n in mine and mine[n] is not None:
            out[n] = {"kg_ha": float(mine[n]), "source": "organisation setting"}
        elif crop is not None:
            s = crop.values[f"ceiling_{n.lower()}_kg_ha"]
            out[n] = {"kg_ha": s.value, "source": f"{crop.name}: {s.source}"}
    return out


def check_ceilings(
    rate_kg_ha: np.ndarray,
    flags: np.ndarray,
    area_m2: np.ndarray,
    seq: np.ndarray,
    spec: Mapping[str, Any],
) -> tuple[np.ndarray, dict[str, Any] | None]:
    """Flag ``above_nutrient_ceiling`` on every cell whose kg of a nutrient per ha (rate x
    the product's fraction) exceeds that nutrient's ceiling; any earlier such flag is
    recomputed (an edit may have lowered the cell). ``spec``: {fractions, ceilings}."""
    bit = FLAG_BITS["above_nutrient_ceiling"]
    fl = np.asarray(flags, dtype=np.uint16) & np.uint16(~bit & 0xFFFF)
    fractions = spec.get("fractions") or {}
    ceilings = spec.get("ceilings") or {}
    checked = [n for n in NUTRIENTS if fractions.get(n) and n in ceilings]
    if not checked:
        return fl, None
    r = np.asarray(rate_kg_ha, dtype=float)
    a = np.asarray(area_m2, dtype=float)
    any_over = np.zeros(len(r), bool)
    per: dict[str, Any] = {}
    for n in checked:
        kg = r * float(fractions[n])
        cap = float(ceilings[n]["kg_ha"])
        over = kg > cap + 1e-9
        any_over |= over
        per[n] = {
            "ceiling_kg_ha": cap,
            "source": ceilings[n]["source"],
            "max_kg_ha": round(float(kg.max()), 3) if len(kg) else 0.0,
            "count": int(over.sum()),
            "area_m2": round(float(a[over].sum()), 3),
        }
    fl[any_over] |= bit
    return fl, {
        "nutrients": per,
        "count": int(any_over.sum()),
        "area_m2": round(float(a[any_over].sum()), 3),
        "area_ha": round(float(a[any_over].sum()) / 1e4, 7),
        "seq": [int(x) for x in np.asarray(seq)[any_over][:MAX_LISTED]],
    }


def check_curve_limits(
    rate_kg_ha: np.ndarray,
    flags: np.ndarray,
    area_m2: np.ndarray,
    seq: np.ndarray,
    curve: tuple[float, float],
    share_max: float = DEFAULT_CURVE_SHARE_MAX,
) -> tuple[np.ndarray, dict[str, Any]]:
    """Share of the field (by area) at the curve's cap (its higher end rate) and floor;
    when a share exceeds ``share_max`` its cells are flagged ``at_curve_limit``."""
    lo, hi = min(curve), max(curve)
    r = np.asarray(rate_kg_ha, dtype=float)
    a = np.asarray(area_m2, dtype=float)
    total = float(a.sum()) or 1.0
    fl = np.asarray(flags, dtype=np.uint16).copy()
    out: dict[str, Any] = {"share_max": share_max, "cap_kg_ha": hi, "floor_kg_ha": lo}
    for name, value in (("cap", hi), ("floor", lo)):
        at = np.isclose(r, value, rtol=0.0, atol=1e-6)
        share = float(a[at].sum()) / total
        flagged = share > share_max
        if flagged:
            fl[at] |= FLAG_BITS["at_curve_limit"]
        out[name] = {
            "count": int(at.sum()),
            "area_m2": round(float(a[at].sum()), 3),
            "share": round(share, 4),
            "flagged": flagged,
            "seq": [int(x) for x in np.asarray(seq)[at][:MAX_LISTED]] if flagged else [],
        }
    return fl, out
