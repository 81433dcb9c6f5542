"""Editing a prescription: per-cell rates or a painted zone make the next version
(edits outside the meter range are refused), and a version's note and legend classes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from fieldrx.agronomy.prescription import apply_cell_edits, check_breaks, paint_zone, summarize
from fieldrx.agronomy.products import product_figures
from fieldrx.db.models import Field, Plan, Prescription, PrescriptionVersion
from fieldrx.geo.crs import to_utm
from fieldrx.services.prescriptions.classes import auto_classes, inherited_classes, legend_classes
from fieldrx.services.prescriptions.meter import meter_of
from fieldrx.services.prescriptions.params import RxError
from fieldrx.services.prescriptions.plausibility import apply_plausibility
from fieldrx.services.prescriptions.versions import get_version, json_safe, max_version, new_version
from fieldrx.store import load_cells, load_rates, load_seq_area


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
    meter = meter_of(rx)
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
    ver = new_version(
        session,
        rx,
        max_version(session, rx) + 1,
        note,
        user_id,
        (seq, new_rates, new_flags, src),
        json_safe(summary),
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
        ver.summary = json_safe({**(ver.summary or {}), "classes": classes})
    session.flush()
    return ver
