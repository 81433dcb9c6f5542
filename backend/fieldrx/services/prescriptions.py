"""Prescriptions in PostGIS: build (pure agronomy) -> versions + per-cell rates (COPY).

A prescription has immutable versions; version n's rates live in
``prescription_rates`` under that version's id, so an edit writes a whole new
rate set (n+1) and never touches n. The metering range the rates are checked
against is kept in ``prescriptions.params["meter"]`` so edits are checked the
same way: model outputs outside it are stored as computed and flagged, edits
outside it are refused (422 naming the limit and the speed).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from fieldrx_edge.metering import calibration_from_dict
from geoalchemy2.shape import to_shape
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from fieldrx.agronomy.cells import FLAG_BITS, CellTable, flag_names
from fieldrx.agronomy.crops import CROPS, Crop, find_crop
from fieldrx.agronomy.interpolate import DEFAULT_METHOD, interpolate_to_cells
from fieldrx.agronomy.plausibility import (
    DEFAULT_CURVE_SHARE_MAX,
    check_ceilings,
    check_curve_limits,
    product_fractions,
    resolve_ceilings,
)
from fieldrx.agronomy.prescription import (
    ATTENTION_MASK,
    MODEL_INPUT,
    PrescriptionError,
    RateRules,
    apply_cell_edits,
    build_prescription,
    check_breaks,
    class_breaks,
    class_table,
    diff_rates,
    paint_zone,
    summarize,
)
from fieldrx.agronomy.products import product_figures
from fieldrx.agronomy.rates import (
    RATE_AT_NDVI_HIGH,
    RATE_AT_NDVI_LOW,
    MeterCheck,
    check_meter_range,
)
from fieldrx.agronomy.zones import zone_cell_values
from fieldrx.db.models import (
    Field,
    Machine,
    Organisation,
    Plan,
    Prescription,
    PrescriptionRate,
    PrescriptionVersion,
    SoilSample,
)
from fieldrx.geo.crs import lonlat_to_utm_xy, to_utm
from fieldrx.store import load_cells, load_rates, load_seq_area, write_rates

MODEL_ALIASES = {"constant": "uniform", "ndvi_linear": "ndvi"}
PARAM_ALIASES = {
    "M": "target_yield_kg_ha",
    "target_yield": "target_yield_kg_ha",
    "x": "n_fraction",
    "nutrient_fraction": "n_fraction",
    "e": "e_kg_per_100kg",
    "uptake_kg_per_100kg": "e_kg_per_100kg",
    "k": "k_utilisation",
    "utilisation": "k_utilisation",
    "rate": "rate_kg_ha",
}
IGNORED_PARAMS = {"nutrient"}
RATE_UNITS = ("kg/ha", "l/ha")


class RxError(ValueError):
    """Bad prescription request; answered as 422 with this message."""


def canonical_model(model: str, params: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """Model name and parameters under the names agronomy.rates uses (aliases accepted)."""
    m = MODEL_ALIASES.get(model, model)
    out: dict[str, Any] = {}
    for k, v in params.items():
        if k in IGNORED_PARAMS:
            continue
        out[PARAM_ALIASES.get(k, k)] = v
    return m, out


def _fill_from_crop(
    model: str, out: dict[str, Any], crop: Crop, sources: dict[str, str], origin: dict[str, str]
) -> None:
    """The crop's defaults for every nutrient-balance parameter the request left out; a
    given value equal to the default counts as the default, another one as an override."""
    if model != "nutrient_balance":
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
        _fill_from_crop(model, out, found, sources, origin)
    if product is not None and model == "nutrient_balance":
        x = float(product.get("n_pct") or 0.0) / 100.0
        if x <= 0:
            raise RxError(f"product {product['name']!r} has no N: nutrient_balance needs N")
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
    if model == "ndvi":
        spec["curve_kg_ha"] = [
            float(params.get("rate_at_low_kg_ha", RATE_AT_NDVI_LOW)),
            float(params.get("rate_at_high_kg_ha", RATE_AT_NDVI_HIGH)),
        ]
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


def legend_classes(
    rates: np.ndarray, area: np.ndarray, breaks: list[float], source: str
) -> dict[str, Any]:
    """A version's legend classes and zones table (class -> ha -> t)."""
    return {"breaks_kg_ha": breaks, "source": source, "table": class_table(rates, area, breaks)}


def auto_classes(rates: np.ndarray, area: np.ndarray, n: int) -> dict[str, Any]:
    lo, hi = (float(rates.min()), float(rates.max())) if len(rates) else (0.0, 1.0)
    # a uniform rate has one class, whatever count was asked
    src = f"{n} equal classes" if hi > lo else "uniform rate: one class"
    return legend_classes(rates, area, class_breaks(lo, hi, n), src)


# said once in a class source, however many edits reach beyond the breaks
_EDITED_CLASS_NOTE = "; edited rates beyond them have a class of their own"


def inherited_classes(
    rates: np.ndarray, area: np.ndarray, base: dict[str, Any] | None
) -> dict[str, Any]:
    """An edit keeps its base version's breaks (the legend does not jump between
    versions). Rates beyond them get a class of their own at that end: widening the
    outer class instead put an edited zone in the colour of the unedited cells (a
    uniform 300 kg/ha map painted at 650 had one class, 300-650, for both)."""
    if not base or not base.get("breaks_kg_ha"):
        return auto_classes(rates, area, 6)
    b = [float(x) for x in base["breaks_kg_ha"]]
    src = str(base.get("source", "")).replace(_EDITED_CLASS_NOTE, "")
    if len(rates):
        lo, hi = float(rates.min()), float(rates.max())
        if lo < b[0]:
            b.insert(0, min(round(lo, 3), b[0] - 1e-3))
        if hi > b[-1]:
            top = b[-1]
            # the last class holds its upper edge: rates on it stay in their class
            if bool((rates == top).any()):
                b[-1] = round(top + 1e-3, 3)
            b.append(max(round(hi, 3), b[-1] + 1e-3))
    if len(b) > len(base["breaks_kg_ha"]) or _EDITED_CLASS_NOTE in str(base.get("source", "")):
        src += _EDITED_CLASS_NOTE
    return legend_classes(rates, area, b, src)


@dataclass
class MeterSpec:
    calibration: dict[str, Any]
    width_m: float
    speed_min_m_s: float
    speed_max_m_s: float

    def check(self) -> MeterCheck:
        return MeterCheck(
            calibration_from_dict(self.calibration),
            self.width_m,
            self.speed_min_m_s,
            self.speed_max_m_s,
        )

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)

    def describe(self) -> dict[str, Any]:
        """The range and the speeds it assumes, for summaries (seed 001 eq. 1-3)."""
        lo, hi = self.check().range_kg_ha()
        return {
            "rate_min_kg_ha": round(lo, 3),
            "rate_max_kg_ha": round(hi, 3),
            "speed_min_kmh": round(self.speed_min_m_s * 3.6, 3),
            "speed_max_kmh": round(self.speed_max_m_s * 3.6, 3),
            "width_m": self.width_m,
            "calibration": self.calibration,
        }


def meter_spec(
    machine: Machine | None,
    plan: Plan,
    speed_min_kmh: float | None,
    speed_max_kmh: float | None,
    width_m: float | None,
    calibration: dict[str, Any] | None,
) -> MeterSpec | None:
    """What the implement can meter: the machine's, overridden by explicit values.

    None (no meter check) when neither a machine nor a speed range is given.
    Without a machine the calibration must be given: no meter is assumed.
    """
    if machine is None and speed_min_kmh is None and speed_max_kmh is None:
        return None
    if machine is not None:
        spec = MeterSpec(
            dict(machine.calibration),
            machine.width_m,
            machine.speed_min_m_s,
            machine.speed_max_m_s,
        )
    else:
        if calibration is None:
            raise RxError(
                "a speed range without machine_id needs calibration (the meter's "
                "q0 = a*r + b: slope_g_min_per_rpm, intercept_g_min, min_rpm, max_rpm): "
                "give machine_id or calibration"
            )
        spec = MeterSpec(
            dict(calibration),
            float((plan.params or {}).get("swath_width_m", 2.3)),
            0.8,
            2.5,
        )
    if speed_min_kmh is not None:
        spec.speed_min_m_s = speed_min_kmh / 3.6
    if speed_max_kmh is not None:
        spec.speed_max_m_s = speed_max_kmh / 3.6
    if width_m is not None:
        spec.width_m = width_m
    if calibration is not None:
        spec.calibration = calibration
    if not 0 < spec.speed_min_m_s <= spec.speed_max_m_s:
        raise RxError(
            f"speed range must satisfy 0 < min <= max, got {spec.speed_min_m_s * 3.6:g}.."
            f"{spec.speed_max_m_s * 3.6:g} km/h"
        )
    try:
        spec.check()
    except (KeyError, TypeError, ValueError) as exc:
        raise RxError(f"invalid metering calibration: {exc}") from exc
    return spec


def field_samples(
    session: Session, field_id: int, column: str, epsg: int
) -> tuple[np.ndarray, np.ndarray]:
    """UTM xy and values of the field's samples that have ``column``."""
    col = getattr(SoilSample, column)
    stmt = select(func.ST_X(SoilSample.geom), func.ST_Y(SoilSample.geom), col).where(
        SoilSample.field_id == field_id, col.is_not(None)
    )
    if column == "n_mg_kg":  # seed 001 eq. 19-21 read alkali-hydrolysable N only
        stmt = stmt.where(SoilSample.n_form == "alkali_hydrolysable")
    rows = session.execute(stmt.order_by(SoilSample.id)).all()
    if not rows:
        return np.zeros((0, 2)), np.zeros(0)
    a = np.asarray(rows, dtype=float)
    x, y = lonlat_to_utm_xy(a[:, 0], a[:, 1], epsg)
    return np.column_stack([x, y]), a[:, 2]


def interpolate_field_samples(
    session: Session,
    field: Field,
    cells: CellTable,
    model: str,
    interpolation: str,
    interpolation_params: dict[str, Any],
) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """The field's samples of the model's input column interpolated onto the cells:
    (values, no_data, description). A cell without data is NaN in ``values``."""
    column = MODEL_INPUT[model]
    assert column is not None
    xy, z = field_samples(session, field.id, column, field.utm_epsg)
    if len(z) == 0:
        what = "soil samples with n_mg_kg" if column == "n_mg_kg" else "samples with ndvi"
        other = (
            session.scalars(
                select(SoilSample.n_form)
                .where(SoilSample.field_id == field.id, SoilSample.n_mg_kg.is_not(None))
                .distinct()
            ).all()
            if column == "n_mg_kg"
            else []
        )
        if other:
            raise RxError(
                f"model {model!r} needs alkali-hydrolysable soil N (seed 001 eq. 19-21); "
                f"field {field.id}'s samples hold {' and '.join(sorted(other))} N, which the "
                "model cannot read as such: import alkali-hydrolysable N, or use another model"
            )
        raise RxError(
            f"model {model!r} needs {what} on field {field.id}: import them first "
            f"(POST /api/v1/fields/{field.id}/soil-samples)"
        )
    res = interpolate_to_cells(
        interpolation, cells.polygons_utm, cells.centroids_utm, xy, z, **interpolation_params
    )
    values = np.where(res.no_data, np.nan, np.asarray(res.values, dtype=float))
    info = {"method": res.method, "n_samples": int(len(z)), **res.info}
    return values, np.asarray(res.no_data, dtype=bool) | np.isnan(values), info


def soil_zone_source(
    session: Session,
    field: Field,
    model: str,
    interpolation: str,
    interpolation_params: dict[str, Any],
    k: int,
    min_area_m2: float,
) -> Callable[[CellTable], tuple[np.ndarray, dict[str, Any]]]:
    """``cell_source`` of a zone prescription from soil samples: the model's input property
    (n_mg_kg for nutrient_balance, sample NDVI for ndvi) interpolated onto the plan's cells,
    classified into ``k`` zones and smoothed to ``min_area_m2`` (``agronomy.zones``, the
    same zoning as imagery NDVI zones); each zone's cells get the zone's mean, so the model
    gives one rate per zone."""
    canonical, _ = canonical_model(model, {})
    column = MODEL_INPUT.get(canonical)
    if column is None:
        raise RxError(
            f"zones need a model with a per-cell input (nutrient_balance: soil n_mg_kg, "
            f"ndvi: sample NDVI), got {model!r}"
        )

    def source(cells: CellTable) -> tuple[np.ndarray, dict[str, Any]]:
        values, _, info = interpolate_field_samples(
            session, field, cells, canonical, interpolation, interpolation_params
        )
        per_cell, zoning = zone_cell_values(
            values,
            k,
            polygons=cells.polygons_utm,
            area_m2=cells.area_m2,
            min_area_m2=min_area_m2,
            value_name=column,
        )
        return per_cell, {**info, **zoning}

    return source


# --------------------------------------------------------------------------- versions


def get_version(session: Session, rx: Prescription, version: int | None) -> PrescriptionVersion:
    n = rx.current_version if version is None else version
    ver = session.scalar(
        select(PrescriptionVersion).where(
            PrescriptionVersion.prescription_id == rx.id, PrescriptionVersion.version == n
        )
    )
    if ver is None:
        raise LookupError(f"prescription {rx.id} has no version {n}")
    return ver


def version_summary(ver: PrescriptionVersion) -> dict[str, Any]:
    return {
        "version": ver.version,
        "note": ver.note,
        "created_at": ver.created_at.isoformat() if ver.created_at else None,
        "created_by": ver.created_by,
        "summary": ver.summary,
    }


def _stats(summary: dict[str, Any]) -> dict[str, Any]:
    """Counts derived from the summary's flags (the summary's own figures are not copied)."""
    out: dict[str, Any] = {}
    fl = summary.get("flagged") or {}
    out["out_of_meter_range_count"] = int(fl.get("below_meter_range", 0)) + int(
        fl.get("above_meter_range", 0)
    )
    out["no_data_count"] = int(fl.get("no_data", 0))
    att = summary.get("attention") or {}
    out["attention_count"] = int(att.get("count", 0))
    out["attention_area_m2"] = float(att.get("area_m2", 0.0))
    interp = summary.get("interpolation") or {}
    if isinstance(interp, dict) and interp.get("loo_rmse") is not None:
        out["kriging_cv_rmse"] = interp["loo_rmse"]
    return out


def prescription_summary(session: Session, rx: Prescription) -> dict[str, Any]:
    vers = session.scalars(
        select(PrescriptionVersion)
        .where(PrescriptionVersion.prescription_id == rx.id)
        .order_by(PrescriptionVersion.version)
    ).all()
    current = next((v for v in vers if v.version == rx.current_version), None)
    summary = current.summary if current is not None else {}
    p = rx.params or {}
    return {
        "id": rx.id,
        "plan_id": rx.plan_id,
        "machine_id": rx.machine_id,
        "name": rx.name,
        "product": rx.product,
        "model": rx.model,
        "params": p.get("model_params", {}),
        "interpolation": p.get("interpolation"),
        "interpolation_params": p.get("interpolation_params", {}),
        "fallback_rate_kg_ha": p.get("fallback_rate_kg_ha"),
        "meter": p.get("meter"),
        "rate_unit": rx_rate_unit(rx)[0],
        "density_kg_l": rx_rate_unit(rx)[1],
        "current_version": rx.current_version,
        "versions": [
            {
                "version": v.version,
                "note": v.note,
                "created_at": v.created_at.isoformat() if v.created_at else None,
            }
            for v in vers
        ],
        "summary": summary,
        "stats": _stats(summary),
        "created_at": rx.created_at.isoformat() if rx.created_at else None,
    }


def _new_version(
    session: Session,
    rx: Prescription,
    version: int,
    note: str,
    user_id: int | None,
    cells: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None],
    summary: dict[str, Any],
) -> PrescriptionVersion:
    """Store version ``version`` with its ``cells``: (seq, rate_kg_ha, flag bits, source
    value), as ``store.load_rates`` returns them (source None: none stored)."""
    seq, rates, flags, source = cells
    ver = PrescriptionVersion(
        prescription_id=rx.id, version=version, note=note, summary=summary, created_by=user_id
    )
    session.add(ver)
    session.flush()
    write_rates(session, ver.id, seq, rates, flags, source)
    rx.current_version = version
    session.flush()
    return ver


def _json_safe(obj: Any) -> Any:
    """Summaries go into JSONB: no NaN / inf, numpy scalars as Python numbers."""
    return json.loads(
        json.dumps(obj, default=lambda o: o.item() if hasattr(o, "item") else str(o)).replace(
            "NaN", "null"
        )
    )


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
    if model not in MODEL_INPUT:
        raise RxError(f"unknown model {model!r} (expected one of {sorted(MODEL_INPUT)})")
    crop_from = "request" if crop is not None else None
    field_crop = find_crop(field.crop) if crop is None else None
    if field_crop is not None:
        crop, crop_from = field_crop.key, "field"
    params, crop_d, param_sources, param_origin = crop_params(
        model, params, crop, spec.product_info
    )
    plaus = plausibility_spec(session, organisation_id, crop, model, params, spec.product_info)
    column = MODEL_INPUT[model]
    if column is None:  # uniform: no geometry needed
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
    rules = RateRules(check, spec.fallback_rate_kg_ha, spec.clamp_min_kg_ha, spec.clamp_max_kg_ha)
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
    summary = _json_safe(summary)
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
    _new_version(session, rx, 1, spec.note or "created", user_id, cells_rates, summary)
    return rx


def check_rate_unit(unit: str, product_info: dict[str, Any] | None) -> None:
    """An l/ha prescription needs a product with a density: the rates are worked out in
    kg/ha (nutrient balance, meter range, product and cost figures all count mass) and
    sent to machines as l/ha = kg/ha / density."""
    if unit not in RATE_UNITS:
        raise RxError(f"rate_unit {unit!r} is not one of {list(RATE_UNITS)}")
    if unit == "l/ha" and not (product_info or {}).get("density_kg_l"):
        what = "no product_key" if product_info is None else f"product {product_info['name']!r}"
        raise RxError(
            f"rate_unit l/ha needs a liquid product with a density (kg/l), got {what}: "
            "choose one or give the product a density"
        )


def rx_rate_unit(rx: Prescription) -> tuple[str, float | None]:
    """The prescription's rate unit and its product's density in kg/l (None: not known)."""
    p = rx.params or {}
    d = (p.get("product_info") or {}).get("density_kg_l")
    return str(p.get("rate_unit") or "kg/ha"), float(d) if d else None


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
    unit = str(b.get("rate_unit") or "kg/ha")
    check_rate_unit(unit, product_info)
    spec = NewPrescription(
        rate_unit=unit,
        name=b.get("name", "") if name is None else name,
        product=b.get("product", ""),
        model=b.get("model", "nutrient_balance"),
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


def _meter_of(rx: Prescription) -> MeterCheck | None:
    m = (rx.params or {}).get("meter")
    return None if not m else MeterSpec(**m).check()


@dataclass(frozen=True)
class RateEdit:
    """A user's change to a version's rates: per-cell rates ``cells`` as (seq, kg/ha), or
    a painted ``zone`` (GeoJSON Polygon or Feature) at ``zone_rate_kg_ha``."""

    cells: list[tuple[int, float]] | None = None
    zone: dict[str, Any] | None = None
    zone_rate_kg_ha: float | None = None


def edit_prescription(
    session: Session,
    rx: Prescription,
    plan: Plan,
    field: Field,
    edit: RateEdit,
    *,
    note: str,
    user_id: int | None,
    based_on: int | None = None,
) -> tuple[PrescriptionVersion, int]:
    """Make the next version from version ``based_on`` (default the current one; the
    version on the user's screen), which is left as it is."""
    from shapely.geometry import shape

    cells, zone, zone_rate_kg_ha = edit.cells, edit.zone, edit.zone_rate_kg_ha

    base = get_version(session, rx, based_on)
    seq, rates, flags, src = load_rates(session, base.id)
    meter = _meter_of(rx)
    if cells is not None:
        if not cells:
            raise RxError("cells: give at least one {seq, rate_kg_ha}")
        edits: dict[int, float] = {}
        for s, r in cells:
            edits[int(s)] = float(r)
        new_rates, new_flags = apply_cell_edits(seq, rates, flags, edits, meter)
        changed = len(edits)
    else:
        if zone is None or zone_rate_kg_ha is None:
            raise RxError("give either cells [{seq, rate_kg_ha}] or zone (Polygon) + rate_kg_ha")
        try:
            geom = shape(zone.get("geometry", zone) if zone.get("type") == "Feature" else zone)
        except (ValueError, TypeError, AttributeError, KeyError, IndexError) as exc:
            raise RxError(f"zone is not a GeoJSON Polygon: {exc}") from exc
        zone_utm = to_utm(geom, field.utm_epsg)
        plan_cells = load_cells(session, plan.id, field.utm_epsg)
        cseq, cent = plan_cells.seq, plan_cells.centroids_utm  # the one centre rule
        if not np.array_equal(cseq, seq):
            raise RxError("the plan's cells do not match the prescription's rates")
        new_rates, new_flags, changed = paint_zone(
            cent, rates, flags, zone_utm, zone_rate_kg_ha, meter
        )
        if changed == 0:
            raise RxError("the zone covers no cell centre of this plan")
    aseq, area = load_seq_area(session, plan.id)
    if not np.array_equal(aseq, seq):
        raise RxError("the plan's cells do not match the prescription's rates")
    plaus = (rx.params or {}).get("plausibility")
    new_flags, plaus_report = apply_plausibility(new_rates, new_flags, area, seq, plaus, False)
    summary = summarize(new_rates, new_flags, area, seq=seq)
    old = base.summary or {}
    if plaus:
        curve = (old.get("plausibility") or {}).get("curve_limits")
        summary["plausibility"] = {**plaus_report, **({"curve_limits": curve} if curve else {})}
    for key in (
        "model",
        "params",
        "meter_range_kg_ha",
        "meter",
        "fallback_rate_kg_ha",
        "interpolation",
        "product",
        "crop",
        "param_sources",
        "param_origin",
        "crop_from",
    ):
        if key in old:
            summary[key] = old[key]
    summary.update(product_figures(new_rates, area, old.get("product")))
    summary["classes"] = inherited_classes(new_rates, np.asarray(area, float), old.get("classes"))
    summary["edited_cells"] = int(changed)
    summary["based_on_version"] = base.version
    ver = _new_version(
        session,
        rx,
        _max_version(session, rx) + 1,
        note,
        user_id,
        (seq, new_rates, new_flags, src),
        _json_safe(summary),
    )
    return ver, int(changed)


def patch_version(
    session: Session,
    rx: Prescription,
    ver: PrescriptionVersion,
    *,
    note: str | None,
    class_count: int | None,
    breaks_kg_ha: list[float] | None,
) -> PrescriptionVersion:
    """A version's note and legend classes (its rates stay as they are; flush only)."""
    if note is not None:
        ver.note = note
    if class_count is not None or breaks_kg_ha is not None:
        seq, rates, _, _ = load_rates(session, ver.id)
        aseq, area = load_seq_area(session, rx.plan_id)
        if not np.array_equal(aseq, seq):
            raise RxError("the plan's cells do not match the prescription's rates")
        a = np.asarray(area, float)
        if breaks_kg_ha is not None:
            classes = legend_classes(rates, a, check_breaks(breaks_kg_ha), "set by user")
        else:
            assert class_count is not None
            classes = auto_classes(rates, a, class_count)
        ver.summary = _json_safe({**(ver.summary or {}), "classes": classes})
    session.flush()
    return ver


def set_current(session: Session, rx: Prescription, version: int) -> None:
    """Make an existing version current (undo / redo move this pointer; versions stay)."""
    get_version(session, rx, version)
    rx.current_version = version
    session.flush()


def diff_versions(
    session: Session, rx: Prescription, va: PrescriptionVersion, vb: PrescriptionVersion
) -> dict[str, Any]:
    """Cells and area whose rate differs between two versions, product and cost delta."""
    seq_a, ra, _, _ = load_rates(session, va.id)
    seq_b, rb, _, _ = load_rates(session, vb.id)
    aseq, area = load_seq_area(session, rx.plan_id)
    if not (np.array_equal(seq_a, seq_b) and np.array_equal(aseq, seq_a)):
        raise RxError("the two versions do not cover the same cells")
    out = diff_rates(seq_a, ra, rb, area)
    sa, sb = va.summary or {}, vb.summary or {}
    ca, cb = sa.get("cost"), sb.get("cost")
    out["cost_delta"] = None if ca is None or cb is None else round(cb - ca, 2)
    ma, mb = sa.get("rate_mean_kg_ha"), sb.get("rate_mean_kg_ha")
    out["rate_mean_delta_kg_ha"] = None if ma is None or mb is None else round(mb - ma, 3)
    return {"from_version": va.version, "to_version": vb.version, **out}


def _max_version(session: Session, rx: Prescription) -> int:
    return int(
        session.scalar(
            select(func.max(PrescriptionVersion.version)).where(
                PrescriptionVersion.prescription_id == rx.id
            )
        )
        or 0
    )


def rates_page(
    session: Session, plan_id: int, version_id: int, limit: int, offset: int
) -> list[dict[str, Any]]:
    """GeoJSON features of cells offset .. offset+limit-1 with this version's rates."""
    plan = session.get(Plan, plan_id)
    field = session.get(Field, plan.field_id) if plan is not None else None
    if plan is None or field is None:
        raise LookupError(f"plan {plan_id} or its field is gone")
    cells = load_cells(session, plan_id, field.utm_epsg, offset, offset + limit)
    seq, rate, masks, src = load_rates(session, version_id, offset, offset + limit)
    keep = np.isin(cells.seq, seq)  # a cell without a rate row is not listed
    cells = cells.take(keep)
    pos = np.searchsorted(seq, cells.seq)
    rate, masks, src = rate[pos], masks[pos], src[pos]
    names = [flag_names(int(m)) for m in masks]
    meter = (masks & (FLAG_BITS["below_meter_range"] | FLAG_BITS["above_meter_range"])) != 0
    feats = cells.geojson_features(
        {
            "seq": cells.seq,
            "swath": cells.swath,
            "area_m2": np.round(cells.area_m2, 3),
            "rate_kg_ha": rate,
            "flags": names,
            # outside what the machine meters at the planned speeds (stored as asked)
            "out_of_meter_range": meter,
            # no sample near enough: the rate is the prescription's fallback rate
            "fallback": (masks & FLAG_BITS["no_data"]) != 0,
            "source_value": src,
        }
    )
    return [json.loads(f) for f in feats]


def job_attention(
    session: Session, rx: Prescription, ver: PrescriptionVersion, machine: Machine
) -> dict[str, Any]:
    """Cells of a version that need the sender's confirmation before a job goes to ``machine``.

    A cell counts when its stored flags say no data / outside the meter range, or
    when the job's machine (its calibration, width and speed range, seed 001
    eq. 1-3) cannot meter its rate although the prescription was checked against
    another meter or none. Returns count, area and the first seq.
    """
    seq, rates, flags, _ = load_rates(session, ver.id)
    plan = session.get(Plan, rx.plan_id)
    if plan is None:
        raise LookupError(f"prescription {rx.id}: plan is gone")
    aseq, area = load_seq_area(session, plan.id)
    if not np.array_equal(aseq, seq):
        raise RxError("the plan's cells do not match the prescription's rates")
    spec = MeterSpec(
        dict(machine.calibration), machine.width_m, machine.speed_min_m_s, machine.speed_max_m_s
    )
    _, meter_flags, _ = check_meter_range(rates, spec.check())
    mask = ((flags & ATTENTION_MASK) != 0) | (meter_flags != 0)
    return {
        "count": int(mask.sum()),
        "area_m2": round(float(np.asarray(area)[mask].sum()), 3),
        "no_data": int(((flags & FLAG_BITS["no_data"]) != 0).sum()),
        "out_of_meter_range": int(
            (
                ((flags & (FLAG_BITS["below_meter_range"] | FLAG_BITS["above_meter_range"])) != 0)
                | (meter_flags != 0)
            ).sum()
        ),
        "above_nutrient_ceiling": int(((flags & FLAG_BITS["above_nutrient_ceiling"]) != 0).sum()),
        "at_curve_limit": int(((flags & FLAG_BITS["at_curve_limit"]) != 0).sum()),
        "seq": [int(x) for x in seq[mask][:50]],
        "meter": spec.describe(),
    }


def version_cells(session: Session, rx: Prescription, ver: PrescriptionVersion) -> CellTable:
    """The plan's cells with this version's rates and flags (for exports / job packages)."""
    plan = session.get(Plan, rx.plan_id)
    field = session.get(Field, plan.field_id) if plan is not None else None
    if plan is None or field is None:
        raise LookupError(f"prescription {rx.id}: plan or field is gone")
    cells = load_cells(session, plan.id, field.utm_epsg)
    seq, rates, flags, _ = load_rates(session, ver.id)
    if not np.array_equal(seq, cells.seq):
        raise RxError("the plan's cells do not match the prescription's rates")
    return cells.with_rates(rates, flags)


def field_boundary_wgs84(session: Session, rx: Prescription) -> Any:
    """(field row, its boundary as a shapely geometry in WGS84) of ``rx``'s plan, or None."""
    plan = session.get(Plan, rx.plan_id)
    field = session.get(Field, plan.field_id) if plan is not None else None
    return None if field is None else (field, to_shape(field.boundary))


__all__ = [
    "PrescriptionError",
    "RxError",
    "PrescriptionRate",
    "create_prescription",
    "edit_prescription",
]
