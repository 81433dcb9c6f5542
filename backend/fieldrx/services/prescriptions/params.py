"""What a prescription request asks for, under the names agronomy uses: model and
parameter aliases, crop and product defaults (and where each value came from), the
rate unit, and what the forms start from. ``RxError`` is a bad request (422).
"""

from __future__ import annotations

from typing import Any

from fieldrx_edge.rateunits.registry import RateUnit, RateUnitError, unit_of, units
from sqlalchemy import select
from sqlalchemy.orm import Session

from fieldrx.agronomy.crops import CROPS, Crop, find_crop
from fieldrx.agronomy.products import NUTRIENTS
from fieldrx.agronomy.ratemodels.registry import model_aliases, param_aliases, rate_models
from fieldrx.db.models import Field, Plan, Prescription

IGNORED_PARAMS = {"nutrient"}
NUTRIENT_KEYS = tuple(col for _, col in NUTRIENTS)


class RxError(ValueError):
    """Bad prescription request; answered as 422 with this message."""


def canonical_model(model: str, params: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """Model name and parameters under the names agronomy.ratemodels uses (each model's
    aliases accepted)."""
    m = model_aliases().get(model, model)
    aliases = param_aliases()
    out: dict[str, Any] = {}
    for k, v in params.items():
        if k in IGNORED_PARAMS:
            continue
        out[aliases.get(k, k)] = v
    return m, out


def fills_from_crop(model: str) -> bool:
    """Whether the crop's and the product's defaults fill model ``model``'s parameters."""
    reg = rate_models()
    return model in reg and reg.get(model).crop_defaults


def fill_from_crop(
    model: str, out: dict[str, Any], crop: Crop, sources: dict[str, str], origin: dict[str, str]
) -> None:
    """The crop's defaults for every nutrient-balance parameter the request left out; a
    given value equal to the default counts as the default, another one as an override."""
    if not fills_from_crop(model):
        return
    defaults: dict[str, float] = {
        **crop.model_defaults(),
        "target_yield_kg_ha": crop.value("target_yield_t_ha") * 1000.0,
    }
    for k, v in defaults.items():
        src_name = "target_yield_t_ha" if k == "target_yield_kg_ha" else k
        src = f"{crop.name}: {crop.values[src_name].source}"
        if k not in out:
            out[k] = v
            sources[k], origin[k] = src, "default"
        elif abs(float(out[k]) - v) <= 1e-9 * max(1.0, abs(v)):
            sources[k], origin[k] = src, "default"
        else:
            sources[k] = f"given (overrides {v:g} from {src})"
            origin[k] = "override"


def crop_params(
    model: str, params: dict[str, Any], crop: str | None, product: dict[str, Any] | None
) -> tuple[dict[str, Any], dict[str, Any] | None, dict[str, str], dict[str, str]]:
    """Fill nutrient-balance parameters the request left out from the crop and the
    product, and say where each came from (what the user gave is never replaced).

    Every crop parameter (``agronomy.crops``: target yield, e, k, eq. 20's a and b) comes
    from the crop, n_fraction from the product's N % / 100; a given n_fraction that
    disagrees with the product's N % is refused rather than one of them silently winning.
    Returns (params, crop, sources, origin) where origin says "default", "override" or
    "given" (a value without a default) per parameter.
    """
    out = dict(params)
    sources = {k: "given" for k in out}
    origin = {k: "given" for k in out}
    crop_d = None
    if crop is not None:
        found = find_crop(crop)
        if found is None or found.key != crop:
            raise RxError(f"unknown crop {crop!r} (expected one of {[c.key for c in CROPS]})")
        crop_d = found.to_dict()
        fill_from_crop(model, out, found, sources, origin)
    if product is not None and fills_from_crop(model):
        x = float(product.get("n_pct") or 0.0) / 100.0
        if x <= 0:
            raise RxError(f"product {product['name']!r} has no N: {model} needs N")
        if "n_fraction" not in out:
            out["n_fraction"] = x
            sources["n_fraction"] = f"{product['name']}: {product['source']}"
            origin["n_fraction"] = "default"
        elif abs(float(out["n_fraction"]) - x) > 1e-9:
            raise RxError(
                f"params.n_fraction {out['n_fraction']} disagrees with product "
                f"{product['name']!r} ({product['n_pct']:g} % N = {x:g}): give one of them"
            )
    return out, crop_d, sources, origin


def form_defaults(session: Session, field: Field) -> dict[str, Any]:
    """What the prescription forms start from on this field: the field's crop (else the
    last prescription's), the last prescription's product and target yield."""
    last = session.scalar(
        select(Prescription)
        .join(Plan, Plan.id == Prescription.plan_id)
        .where(Plan.field_id == field.id)
        .order_by(Prescription.id.desc())
        .limit(1)
    )
    p = (last.params or {}) if last is not None else {}
    crop = find_crop(field.crop)
    crop_from = "field" if crop is not None else None
    if crop is None and p.get("crop"):
        crop, crop_from = find_crop(p["crop"]), "last prescription"
    yield_kg = (p.get("model_params") or {}).get("target_yield_kg_ha")
    return {
        "field_id": field.id,
        "field_crop": field.crop,
        "crop": None if crop is None else crop.key,
        "crop_from": crop_from,
        "product_key": (p.get("product_info") or {}).get("key"),
        "target_yield_t_ha": None if yield_kg is None else float(yield_kg) / 1000.0,
        "from_prescription_id": None if last is None else last.id,
    }


def product_lot(
    product_info: dict[str, Any] | None, lot: dict[str, Any] | None, product: str = ""
) -> dict[str, Any] | None:
    """The product as the prescription keeps it: the catalogue's entry with the lot values
    given with the request (a seed lot's germination, ...) on top; a value given for a
    catalogue product that states another is refused rather than one silently winning."""
    if not lot:
        return product_info
    given = {"name": product or "lot given with the prescription", "source": "given"}
    out = dict(product_info or given)
    for k, v in lot.items():
        had = (product_info or {}).get(k)
        if had is not None and abs(float(had) - float(v)) > 1e-9 * max(1.0, abs(float(had))):
            raise RxError(
                f"lot.{k} {v} disagrees with product {out['name']!r} ({k} {had:g}): give one"
                " of them"
            )
        out[k] = float(v)
    return out


def check_rate_unit(unit: str, product_info: dict[str, Any] | None) -> RateUnit:
    """The prescription's unit, with the product lot values it converts through: the rates
    are worked out in kg/ha (nutrient balance, meter range, product and cost figures all
    count mass) and sent to machines in the unit (l/ha = kg/ha / density, ...)."""
    try:
        u = unit_of(unit)
    except RateUnitError as exc:
        raise RxError(f"rate_unit: {exc}") from None
    what = (
        "no product (product_key or lot)"
        if product_info is None
        else (f"product {product_info.get('name', '')!r}")
    )
    info = product_info or {}
    nutrients = [k for k in NUTRIENT_KEYS if float(info.get(k) or 0.0) > 0]
    if u.seed_lot and nutrients:
        raise RxError(
            f"rate unit {u.name} sows a seed lot, and {what} is a fertiliser "
            f"({', '.join(f'{info[k]:g} {k}' for k in nutrients)}): leave product_key out, "
            "name the seed in product and give its lot values in lot"
        )
    try:
        u.check_lot(product_info, what)
    except RateUnitError as exc:
        raise RxError(f"{exc}: choose a product that states it, or give it in lot") from None
    return u


def rx_rate_unit(rx: Prescription) -> tuple[str, float | None]:
    """The prescription's rate unit and its product's density in kg/l (None: not known)."""
    p = rx.params or {}
    d = (p.get("product_info") or {}).get("density_kg_l")
    return str(p.get("rate_unit") or "kg/ha"), float(d) if d else None


def rx_unit_lot(rx: Prescription) -> tuple[RateUnit, dict[str, float]]:
    """The prescription's rate unit and the product lot values units convert through."""
    p = rx.params or {}
    info = p.get("product_info") or {}
    # every unit's values the product states, not only this unit's: a kg/ha prescription
    # of a liquid still carries its density, so a volume-rate implement can take it
    keys = {v.key for u in units() for v in u.lot}
    return unit_of(p.get("rate_unit")), {
        k: float(info[k]) for k in sorted(keys) if info.get(k) is not None
    }
