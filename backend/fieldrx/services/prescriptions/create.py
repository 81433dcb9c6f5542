"""Version 1 of a prescription: the model's input (soil samples, imagery or none),
rates, clamp, meter and plausibility flags, figures and classes, stored in one flush.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from fieldrx_edge.rateunits.registry import unit_of
from sqlalchemy.orm import Session

from fieldrx.agronomy.cells import CellTable
from fieldrx.agronomy.crops import find_crop
from fieldrx.agronomy.interpolate import DEFAULT_METHOD
from fieldrx.agronomy.prescription import RateRules, build_prescription
from fieldrx.agronomy.products import product_figures
from fieldrx.agronomy.ratemodels.registry import DEFAULT_MODEL, rate_models
from fieldrx.db.models import Field, Machine, Plan, Prescription
from fieldrx.services.prescriptions.classes import auto_classes
from fieldrx.services.prescriptions.meter import MeterSpec, meter_spec
from fieldrx.services.prescriptions.params import (
    RxError,
    canonical_model,
    check_rate_unit,
    crop_params,
    product_lot,
)
from fieldrx.services.prescriptions.plausibility import apply_plausibility, plausibility_spec
from fieldrx.services.prescriptions.samples import interpolate_field_samples
from fieldrx.services.prescriptions.versions import json_safe, new_version
from fieldrx.store import load_cells, load_seq_area


@dataclass(frozen=True)
class NewPrescription:
    """What version 1 of a prescription is made from (``create_prescription``).

    ``cell_source`` replaces the soil-sample interpolation: it gets the plan's cells and
    returns the model's per-cell input (NaN = no data) and a description for the summary
    (imagery NDVI uses it); ``source`` is recorded in the prescription's params.
    """

    name: str
    product: str
    model: str
    params: dict[str, Any]
    interpolation: str
    interpolation_params: dict[str, Any]
    fallback_rate_kg_ha: float | None
    meter: MeterSpec | None
    machine_id: int | None
    cell_source: Callable[[CellTable], tuple[np.ndarray, dict[str, Any]]] | None = None
    source: dict[str, Any] | None = None
    crop: str | None = None
    product_info: dict[str, Any] | None = None
    clamp_min_kg_ha: float | None = None
    clamp_max_kg_ha: float | None = None
    class_count: int = 6
    note: str = ""
    rate_unit: str = "kg/ha"


def create_prescription(
    session: Session,
    plan: Plan,
    field: Field,
    spec: NewPrescription,
    *,
    user_id: int | None,
    organisation_id: int,
) -> Prescription:
    """Interpolate, rate, clamp and store version 1 (flush only). Raises ValueError subclasses."""
    crop = spec.crop
    model, params = canonical_model(spec.model, spec.params)
    models = rate_models()
    if model not in models:
        raise RxError(f"unknown model {model!r} (expected one of {sorted(models.names())})")
    crop_from = "request" if crop is not None else None
    field_crop = find_crop(field.crop) if crop is None else None
    if field_crop is not None:
        crop, crop_from = field_crop.key, "field"
    params, crop_d, param_sources, param_origin = crop_params(
        model, params, crop, spec.product_info
    )
    plaus = plausibility_spec(session, organisation_id, crop, model, params, spec.product_info)
    column = models.get(model).input
    if column is None:  # a uniform rate: no geometry needed
        seq, area = load_seq_area(session, plan.id)
        cells = None
    else:
        cells = load_cells(session, plan.id, field.utm_epsg)
        seq, area = cells.seq, cells.area_m2
    if len(seq) == 0:
        raise RxError(f"plan {plan.id} has no cells")
    check = None if spec.meter is None else spec.meter.check()
    values = no_data = None
    interp_info: dict[str, Any] | None = None
    if cells is not None and column is not None and spec.cell_source is not None:
        values, interp_info = spec.cell_source(cells)
        values = np.asarray(values, dtype=float)
        no_data = np.isnan(values)
        if no_data.all():
            raise RxError(f"the {model!r} input source has no data for any cell of plan {plan.id}")
    elif cells is not None and column is not None:
        values, no_data, interp_info = interpolate_field_samples(
            session, field, cells, model, spec.interpolation, spec.interpolation_params
        )
    unit = unit_of(spec.rate_unit)
    # a model that prescribes in the prescription's unit (seeds/ha): its rates to kg/ha
    # through the product lot check_rate_unit accepted
    per_unit = (
        unit.kg_per_unit(unit.check_lot(spec.product_info))
        if models.get(model).rates_in_unit
        else 1.0
    )
    rules = RateRules(
        check, spec.fallback_rate_kg_ha, spec.clamp_min_kg_ha, spec.clamp_max_kg_ha, per_unit
    )
    p = build_prescription(model, params, len(seq), values, no_data, rules, area, seq)
    flags, plaus_report = apply_plausibility(p.rate_kg_ha, p.flags, area, seq, plaus, True)
    p.flags = flags
    summary = p.summary(area, seq=seq)
    summary["plausibility"] = plaus_report
    if interp_info is not None:
        summary["interpolation"] = interp_info
    if spec.meter is not None:
        summary["meter"] = spec.meter.describe()
    summary.update(product_figures(p.rate_kg_ha, area, spec.product_info))
    summary["product"] = spec.product_info
    summary["crop"] = crop_d
    summary["crop_from"] = crop_from
    summary["param_sources"] = param_sources
    summary["param_origin"] = param_origin
    summary["classes"] = auto_classes(p.rate_kg_ha, np.asarray(area, float), spec.class_count)
    summary = json_safe(summary)
    rx = Prescription(
        organisation_id=organisation_id,
        plan_id=plan.id,
        machine_id=spec.machine_id,
        name=spec.name or f"{model} on plan {plan.id}",
        product=spec.product or (spec.product_info or {}).get("name", ""),
        model=model,
        params={
            "model_params": params,
            "interpolation": None if column is None else spec.interpolation,
            "interpolation_params": spec.interpolation_params,
            "fallback_rate_kg_ha": spec.fallback_rate_kg_ha,
            "meter": None if spec.meter is None else spec.meter.to_dict(),
            "product_info": spec.product_info,
            "clamp": {"min_kg_ha": spec.clamp_min_kg_ha, "max_kg_ha": spec.clamp_max_kg_ha},
            "plausibility": plaus,
            "crop": crop,
            **({"source": spec.source} if spec.source else {}),
            **({"rate_unit": spec.rate_unit} if spec.rate_unit != "kg/ha" else {}),
        },
        current_version=1,
    )
    session.add(rx)
    session.flush()
    cells_rates = (seq, p.rate_kg_ha, p.flags, values)
    new_version(session, rx, 1, spec.note or "created", user_id, cells_rates, summary)
    return rx


def create_from_request(
    session: Session,
    plan: Plan,
    field: Field,
    machine: Machine | None,
    b: dict[str, Any],
    *,
    organisation_id: int,
    user_id: int | None,
    name: str | None = None,
    **extra: Any,
) -> Prescription:
    """Version 1 from a ``PrescriptionIn`` body as a dict (the API route and the background
    task share it): meter, catalogue product, crop defaults, clamp, classes, note."""
    from fieldrx.services.products import resolve_product

    meter = meter_spec(
        machine,
        plan,
        b.get("speed_min_kmh"),
        b.get("speed_max_kmh"),
        b.get("width_m"),
        b.get("calibration"),
    )
    product_info = None
    if b.get("product_key"):
        product_info = resolve_product(session, organisation_id, b["product_key"])
        if product_info is None:
            raise RxError(f"product_key {b['product_key']!r} is not in this catalogue")
    product_info = product_lot(product_info, b.get("lot"), b.get("product", ""))
    unit = str(b.get("rate_unit") or "kg/ha")
    check_rate_unit(unit, product_info)
    spec = NewPrescription(
        rate_unit=unit,
        name=b.get("name", "") if name is None else name,
        product=b.get("product", ""),
        model=b.get("model", DEFAULT_MODEL),
        params=b.get("params") or {},
        interpolation=b.get("interpolation", DEFAULT_METHOD),
        interpolation_params=b.get("interpolation_params") or {},
        fallback_rate_kg_ha=b.get("fallback_rate_kg_ha"),
        meter=meter,
        machine_id=b.get("machine_id"),
        crop=b.get("crop"),
        product_info=product_info,
        clamp_min_kg_ha=b.get("clamp_min_kg_ha"),
        clamp_max_kg_ha=b.get("clamp_max_kg_ha"),
        class_count=int(b.get("class_count") or 6),
        note=b.get("note", ""),
        **extra,
    )
    return create_prescription(
        session, plan, field, spec, user_id=user_id, organisation_id=organisation_id
    )
