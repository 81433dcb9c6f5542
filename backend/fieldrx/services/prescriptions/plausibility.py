"""Plausibility of a rate map: what it is checked against (organisation and crop
ceilings, a rate curve's end points), stored with the prescription so edits are checked
the same way, and the flags and summary block the check gives.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from fieldrx.agronomy.crops import find_crop
from fieldrx.agronomy.plausibility import (
    DEFAULT_CURVE_SHARE_MAX,
    check_ceilings,
    check_curve_limits,
    product_fractions,
    resolve_ceilings,
)
from fieldrx.agronomy.ratemodels.registry import find_model
from fieldrx.db.models import Organisation


def plausibility_spec(
    session: Session,
    organisation_id: int,
    crop: str | None,
    model: str,
    params: dict[str, Any],
    product: dict[str, Any] | None,
) -> dict[str, Any]:
    """What the rate map is checked against (stored with the prescription so edits are
    checked the same way): nutrient fractions, ceilings (organisation over crop) and, for
    a rate curve, its end points and the share of the field allowed at one of them."""
    org = session.get(Organisation, organisation_id)
    settings = dict((org.agronomy if org is not None else None) or {})
    spec: dict[str, Any] = {
        "fractions": product_fractions(product, params),
        "ceilings": resolve_ceilings(find_crop(crop), settings.get("ceilings_kg_ha")),
    }
    rate_model = find_model(model)
    curve = None if rate_model is None else rate_model.curve_kg_ha(params)
    if curve is not None:
        spec["curve_kg_ha"] = [float(curve[0]), float(curve[1])]
        spec["curve_share_max"] = float(settings.get("curve_share_max", DEFAULT_CURVE_SHARE_MAX))
    return spec


def apply_plausibility(
    rates: np.ndarray,
    flags: np.ndarray,
    area: np.ndarray,
    seq: np.ndarray,
    spec: dict[str, Any] | None,
    curve: bool,
) -> tuple[np.ndarray, dict[str, Any]]:
    """Ceiling flags on every cell (recomputed), curve-limit flags on model output only
    (``curve``); returns the new flags and the summary's ``plausibility`` block."""
    if not spec:
        return np.asarray(flags, dtype=np.uint16), {}
    fl, ceil = check_ceilings(rates, flags, area, seq, spec)
    out: dict[str, Any] = {"ceilings": spec.get("ceilings"), "fractions": spec.get("fractions")}
    out["above_ceiling"] = ceil
    if curve and spec.get("curve_kg_ha"):
        lo, hi = spec["curve_kg_ha"]
        fl, out["curve_limits"] = check_curve_limits(
            rates, fl, area, seq, (lo, hi), spec["curve_share_max"]
        )
    return fl, out
