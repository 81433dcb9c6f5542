"""A prescription's immutable versions: storing one with its rates, finding one, the
current pointer (undo / redo), comparing two, and reading a version's rates and summary
back (pages of cells, exports, job packages).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
from geoalchemy2.shape import to_shape
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from fieldrx.agronomy.cells import FLAG_BITS, CellTable, flag_names
from fieldrx.agronomy.prescription import diff_rates
from fieldrx.db.models import Field, Plan, Prescription, PrescriptionVersion
from fieldrx.services.prescriptions.params import RxError, rx_rate_unit, rx_unit_lot
from fieldrx.store import load_cells, load_rates, load_seq_area, write_rates


def report_unit(rx: Prescription, planned_kg: float, applied_kg: float) -> dict[str, Any]:
    """A job's totals in its prescription's unit (seeds, litres, ...), beside its kg."""
    u = unit_figures(rx)
    k = u["kg_per_unit"]
    name = rx_rate_unit(rx)[0]
    return {
        "rate_unit": name,
        **u,
        "total_unit": name.removesuffix("/ha"),
        "planned_total": None if k is None else planned_kg / k,
        "applied_total": None if k is None else applied_kg / k,
    }


def unit_figures(rx: Prescription) -> dict[str, Any]:
    """The unit's lot values and kg/ha in 1 unit/ha (None: the lot does not say), so a
    client shows the kg/ha rates in the prescription's unit without its own arithmetic."""
    unit, lot = rx_unit_lot(rx)
    return {"lot": lot, "kg_per_unit": unit.kg_per_unit(lot) if unit.known(lot) else None}


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
        **unit_figures(rx),
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


def new_version(
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


def json_safe(obj: Any) -> Any:
    """Summaries go into JSONB: no NaN / inf, numpy scalars as Python numbers."""
    return json.loads(
        json.dumps(obj, default=lambda o: o.item() if hasattr(o, "item") else str(o)).replace(
            "NaN", "null"
        )
    )


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


def max_version(session: Session, rx: Prescription) -> int:
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
