"""Pure prescription building: cells + data + model -> rates, flags, summary.

No database: the API layer stores what these functions return as a new
prescription version. Every function returns new arrays and never mutates its
inputs, so version n stays unchanged when version n+1 is made from it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely

from fieldrx.agronomy.cells import FLAG_BITS, CellTable
from fieldrx.agronomy.interpolate import DEFAULT_METHOD, InterpolationResult, interpolate_to_cells
from fieldrx.agronomy.ratemodels.registry import needs_input
from fieldrx.agronomy.rates import (
    MeterCheck,
    check_meter_range,
    model_rates,
    require_meterable,
)


class PrescriptionError(ValueError):
    """Bad edit, zone or input; the message names the cell or parameter."""


@dataclass
class Prescription:
    """Rates in path order with per-cell flag bits (see ``cells.FLAG_BITS``)."""

    rate_kg_ha: np.ndarray
    flags: np.ndarray
    model: str
    params: dict[str, Any]
    meter_range_kg_ha: tuple[float, float] | None = None
    fallback_rate_kg_ha: float | None = None
    info: dict[str, Any] = field(default_factory=dict)
    clamp: dict[str, Any] | None = None

    def summary(
        self, area_m2: np.ndarray, bins: int = 10, seq: np.ndarray | None = None
    ) -> dict[str, Any]:
        out = summarize(self.rate_kg_ha, self.flags, area_m2, bins=bins, seq=seq)
        out["model"] = self.model
        out["params"] = self.params
        out["meter_range_kg_ha"] = (
            None if self.meter_range_kg_ha is None else list(self.meter_range_kg_ha)
        )
        out["fallback_rate_kg_ha"] = self.fallback_rate_kg_ha
        if self.clamp is not None:
            out["clamp"] = self.clamp
        out.update({k: v for k, v in self.info.items() if k not in out})
        return out


# Flags that mean "the machine will not apply what this cell asks for, or the
# rate is a guess": a job with such cells is sent only on explicit confirmation.
ATTENTION_FLAGS = (
    "no_data",
    "below_meter_range",
    "above_meter_range",
    "above_nutrient_ceiling",
    "at_curve_limit",
)
ATTENTION_MASK = sum(FLAG_BITS[n] for n in ATTENTION_FLAGS)


def _finalise(
    rates: np.ndarray, base_flags: np.ndarray, meter: MeterCheck | None
) -> tuple[np.ndarray, np.ndarray, tuple[float, float] | None]:
    same, meter_flags, rng = check_meter_range(rates, meter)
    return same, (base_flags | meter_flags).astype(np.uint16), rng


@dataclass(frozen=True)
class RateRules:
    """How a model's rates are completed and bounded.

    Cells without data get ``fallback_rate_kg_ha``, or when None the model's rate at the
    area-weighted mean of the cells that have data. Then the agronomist's clamp
    (``clamp_min_kg_ha`` / ``clamp_max_kg_ha``, see ``clamp_rates``) and the ``meter``
    range check (kept as computed and flagged, see ``rates.check_meter_range``).
    ``model_kg_per_unit``: kg/ha in one of the model's rates, for a model whose rates are in
    the prescription's unit (``RateModel.rates_in_unit``: seeds/ha through a seed lot); 1
    for a model that gives kg/ha of product.
    """

    meter: MeterCheck | None = None
    fallback_rate_kg_ha: float | None = None
    clamp_min_kg_ha: float | None = None
    clamp_max_kg_ha: float | None = None
    model_kg_per_unit: float = 1.0


def build_prescription(
    model: str,
    params: Mapping[str, Any],
    n_cells: int,
    values: np.ndarray | None = None,
    no_data: np.ndarray | None = None,
    rules: RateRules = RateRules(),
    area_m2: np.ndarray | None = None,
    seq: np.ndarray | None = None,
) -> Prescription:
    """Rates from per-cell values (NaN / ``no_data`` = no data), completed and bounded by
    ``rules``: cells without data get the fallback and are flagged ``no_data``; every
    cell the clamp changes is flagged and counted; the meter range is checked."""
    params = dict(params)
    if not needs_input(model):
        raw = model_rates(model, None, params, n_cells) * rules.model_kg_per_unit
        flags = np.zeros(n_cells, dtype=np.uint16)
        fb = None
    else:
        if values is None:
            raise PrescriptionError(f"model {model!r} needs per-cell values (soil samples or NDVI)")
        v = np.asarray(values, dtype=float)
        if len(v) != n_cells:
            raise PrescriptionError(f"{len(v)} values for {n_cells} cells")
        nd = np.isnan(v) if no_data is None else (np.asarray(no_data, dtype=bool) | np.isnan(v))
        raw = model_rates(model, v, params, n_cells) * rules.model_kg_per_unit
        fb = rules.fallback_rate_kg_ha
        if fb is None:
            have = ~nd
            if not have.any():
                raise PrescriptionError("no cell has data and no fallback_rate_kg_ha was given")
            w = np.ones(n_cells) if area_m2 is None else np.asarray(area_m2, dtype=float)
            mean_v = float(np.average(v[have], weights=w[have]))
            fb = float(model_rates(model, np.array([mean_v]), params, 1)[0])
            fb *= rules.model_kg_per_unit
        elif not (np.isfinite(fb) and fb >= 0):
            raise PrescriptionError(f"fallback_rate_kg_ha must be >= 0, got {fb!r}")
        raw = np.where(nd, fb, raw)
        flags = np.where(nd, FLAG_BITS["no_data"], 0).astype(np.uint16)
    clamp = None
    lo, hi = rules.clamp_min_kg_ha, rules.clamp_max_kg_ha
    if lo is not None or hi is not None:
        raw, flags, clamp = clamp_rates(raw, flags, lo, hi, area_m2, seq)
    rates, flags, rng = _finalise(raw, flags, rules.meter)
    return Prescription(rates, flags, model, params, rng, fb, clamp=clamp)


def clamp_rates(
    rate_kg_ha: np.ndarray,
    flags: np.ndarray,
    lo: float | None,
    hi: float | None,
    area_m2: np.ndarray | None = None,
    seq: np.ndarray | None = None,
    max_listed: int = 1000,
) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """The agronomist's min / max rate applied to model rates, never silently.

    Every rate below ``lo`` becomes ``lo`` (flag ``clamped_min``), every rate above
    ``hi`` becomes ``hi`` (``clamped_max``); the report gives both counts, their area,
    the model's range before the clamp and the first ``max_listed`` cells by seq.
    """
    if lo is not None and hi is not None and lo > hi:
        raise PrescriptionError(f"clamp minimum {lo:g} kg/ha exceeds the maximum {hi:g} kg/ha")
    for name, v in (("minimum", lo), ("maximum", hi)):
        if v is not None and not (np.isfinite(v) and v >= 0):
            raise PrescriptionError(f"clamp {name} must be a rate >= 0 kg/ha, got {v!r}")
    r = np.asarray(rate_kg_ha, dtype=float)
    fl = np.array(flags, dtype=np.uint16)
    below = np.zeros(len(r), bool) if lo is None else r < lo
    above = np.zeros(len(r), bool) if hi is None else r > hi
    out = np.clip(r, -np.inf if lo is None else lo, np.inf if hi is None else hi)
    fl[below] |= FLAG_BITS["clamped_min"]
    fl[above] |= FLAG_BITS["clamped_max"]
    a = np.ones(len(r)) if area_m2 is None else np.asarray(area_m2, dtype=float)
    changed = below | above
    report: dict[str, Any] = {
        "min_kg_ha": lo,
        "max_kg_ha": hi,
        "raised": int(below.sum()),
        "lowered": int(above.sum()),
        "count": int(changed.sum()),
        "area_m2": round(float(a[changed].sum()), 3),
        "model_min_kg_ha": round(float(r.min()), 3) if len(r) else None,
        "model_max_kg_ha": round(float(r.max()), 3) if len(r) else None,
        "seq": None if seq is None else [int(x) for x in np.asarray(seq)[changed][:max_listed]],
    }
    return out, fl, report


def prescribe(
    cells: CellTable,
    model: str,
    params: Mapping[str, Any],
    sample_xy_utm: np.ndarray | None = None,
    sample_values: np.ndarray | None = None,
    interpolation: str = DEFAULT_METHOD,
    interpolation_params: Mapping[str, Any] | None = None,
    rules: RateRules = RateRules(),
) -> Prescription:
    """Interpolate samples onto the cells, then ``build_prescription``.

    ``sample_xy_utm`` must be in ``cells.epsg``. ``info`` of the result carries
    the interpolation report (method, LOO-CV RMSE for kriging, no-data count).
    """
    interp: InterpolationResult | None = None
    if needs_input(model):
        if sample_xy_utm is None or sample_values is None or len(sample_values) == 0:
            raise PrescriptionError(f"model {model!r} needs samples")
        interp = interpolate_to_cells(
            interpolation,
            cells.polygons_utm,
            cells.centroids_utm,
            sample_xy_utm,
            sample_values,
            **dict(interpolation_params or {}),
        )
    p = build_prescription(
        model,
        params,
        len(cells),
        None if interp is None else interp.values,
        None if interp is None else interp.no_data,
        rules,
        cells.area_m2,
    )
    if interp is not None:
        p.info["interpolation"] = {"method": interp.method, **interp.info}
    return p


def apply_cell_edits(
    seq: np.ndarray,
    rate_kg_ha: np.ndarray,
    flags: np.ndarray,
    edits: Mapping[int, float],
    meter: MeterCheck | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Manual per-cell rates by cell ``seq``; returns new (rates, flags).

    Edited cells are flagged ``manual`` (their old flags are replaced, they
    no longer carry a fallback). A rate the meter cannot deliver at the planned
    speeds is refused (``MeterRangeError`` naming the limit and the speed),
    never stored as something else.
    """
    seq = np.asarray(seq)
    pos = {int(s): i for i, s in enumerate(seq.tolist())}
    rates = np.array(rate_kg_ha, dtype=float)
    fl = np.array(flags, dtype=np.uint16)
    idx: list[int] = []
    vals: list[float] = []
    for s, r in edits.items():
        if int(s) not in pos:
            raise PrescriptionError(f"cell {s} does not exist in this plan")
        r = float(r)
        if not np.isfinite(r) or r < 0:
            raise PrescriptionError(f"cell {s}: rate must be >= 0, got {r!r}")
        require_meterable(r, meter, f"cell {s}")
        idx.append(pos[int(s)])
        vals.append(r)
    ii = np.array(idx, dtype=np.int64)
    new, meter_flags, _ = check_meter_range(np.array(vals), meter)
    rates[ii] = new
    fl[ii] = FLAG_BITS["manual"] | meter_flags
    return rates, fl


def cells_in_zone(centroids_utm: np.ndarray, zone_utm: Any) -> np.ndarray:
    """Cells whose centroid lies in the zone polygon (border included): a bool mask."""
    if (
        zone_utm is None
        or zone_utm.is_empty
        or zone_utm.geom_type
        not in (
            "Polygon",
            "MultiPolygon",
        )
    ):
        raise PrescriptionError("zone must be a non-empty Polygon or MultiPolygon")
    if not zone_utm.is_valid:
        raise PrescriptionError(f"zone polygon is invalid: {shapely.is_valid_reason(zone_utm)}")
    c = np.asarray(centroids_utm, dtype=float)
    return np.asarray(shapely.intersects_xy(zone_utm, c[:, 0], c[:, 1]))


def paint_zone(
    centroids_utm: np.ndarray,
    rate_kg_ha: np.ndarray,
    flags: np.ndarray,
    zone_utm: Any,
    zone_rate_kg_ha: float,
    meter: MeterCheck | None = None,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Zone painting: every cell covered by the polygon (centroid inside) gets the rate.

    Returns new (rates, flags, number of cells painted); painted cells are
    flagged ``zone``. A rate the meter cannot deliver is refused like a cell
    edit (``rates.require_meterable``). The zone is in the cells' UTM zone.
    """
    r = float(zone_rate_kg_ha)
    if not np.isfinite(r) or r < 0:
        raise PrescriptionError(f"zone rate must be >= 0, got {zone_rate_kg_ha!r}")
    require_meterable(r, meter, "zone rate")
    mask = cells_in_zone(centroids_utm, zone_utm)
    rates = np.array(rate_kg_ha, dtype=float)
    fl = np.array(flags, dtype=np.uint16)
    new, meter_flags, _ = check_meter_range(np.array([r]), meter)
    rates[mask] = new[0]
    fl[mask] = FLAG_BITS["zone"] | meter_flags[0]
    return rates, fl, int(mask.sum())


def planned_kg(rate_kg_ha: np.ndarray, area_m2: np.ndarray) -> float:
    """Planned product mass (kg) of cells: sum(rate_kg_ha * area_m2) / 10 000 (1 ha =
    10 000 m^2), each cell's area being what it covers inside the field (``Cells.area_m2``,
    the field's UTM plane). The one definition of a planned amount: a prescription
    version's, a job's (its report, print view and exports), an imported version's."""
    r = np.asarray(rate_kg_ha, dtype=float)
    return float((r * np.asarray(area_m2, dtype=float)).sum() / 1e4)


OUTCOME_TOLERANCE_PCT = 10.0  # a cell is under / over-applied beyond +-10 % of its target


def application_outcome(
    target_kg_ha: np.ndarray, applied_kg_ha: np.ndarray, area_m2: np.ndarray
) -> dict[str, float | None]:
    """The agronomic outcome of a job over its cells: target and applied mass (kg, by
    ``planned_kg``) and mean rate (kg/ha over the cells' area), the relative difference,
    and the share of the area (%) applied more than ``OUTCOME_TOLERANCE_PCT`` below or
    above its target. Cells with a target of 0 count in neither share."""
    t = np.nan_to_num(np.asarray(target_kg_ha, dtype=float))
    a = np.nan_to_num(np.asarray(applied_kg_ha, dtype=float))
    w = np.asarray(area_m2, dtype=float)
    area = float(w.sum())
    target_kg, applied_kg = planned_kg(t, w), planned_kg(a, w)
    k = OUTCOME_TOLERANCE_PCT / 100.0
    aimed = t > 0
    under = float(w[aimed & (a < (1 - k) * t)].sum())
    over = float(w[aimed & (a > (1 + k) * t)].sum())
    aimed_area = float(w[aimed].sum())
    return {
        "area_m2": area,
        "target_kg": target_kg,
        "applied_kg": applied_kg,
        "target_kg_ha": target_kg * 1e4 / area if area > 0 else None,
        "applied_kg_ha": applied_kg * 1e4 / area if area > 0 else None,
        "difference_pct": 100.0 * (applied_kg - target_kg) / target_kg if target_kg > 0 else None,
        "under_area_pct": 100.0 * under / aimed_area if aimed_area > 0 else None,
        "over_area_pct": 100.0 * over / aimed_area if aimed_area > 0 else None,
        "tolerance_pct": OUTCOME_TOLERANCE_PCT,
    }


def summarize(
    rate_kg_ha: np.ndarray,
    flags: np.ndarray,
    area_m2: np.ndarray,
    bins: int = 10,
    seq: np.ndarray | None = None,
    max_listed: int = 1000,
) -> dict[str, Any]:
    """Area, product mass, area-weighted mean / min / max, histogram, flagged cells.

    Product mass = sum(rate_kg_ha * area_m2) / 10 000 (1 ha = 10 000 m^2).
    Figures are rounded to 0.001 (kg/ha, kg, m^2) for display.
    The histogram has ``bins`` equal-width classes over [min, max], each with
    its cell count and area. With ``seq``, the first ``max_listed`` flagged
    cells are listed by seq.
    """
    r = np.asarray(rate_kg_ha, dtype=float)
    a = np.asarray(area_m2, dtype=float)
    fl = np.asarray(flags, dtype=np.int64)
    total_area = float(a.sum())
    if len(r) == 0:
        return {"n_cells": 0, "area_m2": 0.0, "area_ha": 0.0, "product_kg": 0.0}
    lo, hi = float(r.min()), float(r.max())
    edges = np.linspace(lo, hi if hi > lo else lo + 1.0, bins + 1)
    counts, _ = np.histogram(r, bins=edges)
    areas, _ = np.histogram(r, bins=edges, weights=a)
    flagged = {name: int(((fl & bit) != 0).sum()) for name, bit in FLAG_BITS.items()}
    flagged_area = {
        name: round(float(a[(fl & bit) != 0].sum()), 3) for name, bit in FLAG_BITS.items()
    }
    flagged_seq_mask = fl != 0
    attention = (fl & ATTENTION_MASK) != 0
    return {
        "n_cells": int(len(r)),
        "area_m2": round(total_area, 3),
        "area_ha": round(total_area / 1e4, 7),
        "product_kg": round(planned_kg(r, a), 3),
        "rate_mean_kg_ha": round(
            float(np.average(r, weights=a)) if total_area > 0 else float(r.mean()), 3
        ),
        "rate_min_kg_ha": round(lo, 3),
        "rate_max_kg_ha": round(hi, 3),
        "histogram": {
            "edges_kg_ha": [round(float(e), 3) for e in edges],
            "counts": [int(c) for c in counts],
            "area_m2": [round(float(x), 3) for x in areas],
        },
        "flagged": flagged,
        "flagged_area_m2": flagged_area,
        "n_flagged": int(flagged_seq_mask.sum()),
        # cells the machine will not apply as asked (meter range) or whose rate is a
        # fallback (no data): count, area and seq, shown wherever the prescription is
        "attention": {
            "flags": list(ATTENTION_FLAGS),
            "count": int(attention.sum()),
            "area_m2": round(float(a[attention].sum()), 3),
            "area_ha": round(float(a[attention].sum()) / 1e4, 7),
            "seq": None
            if seq is None
            else [int(x) for x in np.asarray(seq)[attention][:max_listed]],
        },
        "flagged_seq": None
        if seq is None
        else [int(x) for x in np.asarray(seq)[flagged_seq_mask][:max_listed]],
    }


def class_breaks(lo: float, hi: float, n: int) -> list[float]:
    """``n`` equal-width rate classes over [lo, hi] (one class 1 kg/ha wide when lo == hi)."""
    if n < 1:
        raise PrescriptionError(f"class count must be >= 1, got {n}")
    if hi <= lo:
        return [round(lo, 3), round(lo + 1.0, 3)]
    return [round(float(e), 3) for e in np.linspace(lo, hi, n + 1)]


def check_breaks(breaks: list[float]) -> list[float]:
    """Breaks typed by a person: at least two, finite, strictly increasing (422 otherwise)."""
    b = [float(x) for x in breaks]
    if len(b) < 2:
        raise PrescriptionError("class breaks (kg/ha): give at least two edges (one class)")
    for i, (x, y) in enumerate(zip(b, b[1:], strict=False)):
        if not (np.isfinite(x) and np.isfinite(y)) or y <= x:
            raise PrescriptionError(
                f"class breaks (kg/ha) must increase: edge {i + 1} ({y:g}) <= edge {i} ({x:g})"
            )
    return b


def class_table(
    rate_kg_ha: np.ndarray, area_m2: np.ndarray, breaks: list[float]
) -> list[dict[str, Any]]:
    """Zones table of a version: per legend class, cells, ha and t of product.

    Class i holds breaks[i] <= rate < breaks[i+1] (the last class includes its upper
    edge); rates outside the breaks go to the first / last class, like the map's colour
    steps. Product t = sum(rate * area_m2) / 1e4 / 1000.
    """
    r = np.asarray(rate_kg_ha, dtype=float)
    a = np.asarray(area_m2, dtype=float)
    k = len(breaks) - 1
    idx = np.clip(np.searchsorted(np.asarray(breaks), r, side="right") - 1, 0, k - 1)
    out = []
    for i in range(k):
        m = idx == i
        out.append(
            {
                "class": i + 1,
                "from_kg_ha": breaks[i],
                "to_kg_ha": breaks[i + 1],
                "n_cells": int(m.sum()),
                "area_ha": round(float(a[m].sum()) / 1e4, 6),
                "product_t": round(float((r[m] * a[m]).sum()) / 1e7, 6),
            }
        )
    return out


def diff_rates(
    seq: np.ndarray,
    rate_a: np.ndarray,
    rate_b: np.ndarray,
    area_m2: np.ndarray,
    max_listed: int = 1000,
    tol_kg_ha: float = 1e-9,
) -> dict[str, Any]:
    """What changed from rate map a to b over the same cells: cells and area whose rate
    differs, product delta kg (b - a, sum(rate * area) / 1e4) and the largest change."""
    ra = np.asarray(rate_a, dtype=float)
    rb = np.asarray(rate_b, dtype=float)
    a = np.asarray(area_m2, dtype=float)
    d = rb - ra
    changed = np.abs(d) > tol_kg_ha
    return {
        "cells_changed": int(changed.sum()),
        "area_changed_m2": round(float(a[changed].sum()), 3),
        "area_changed_ha": round(float(a[changed].sum()) / 1e4, 6),
        "product_kg_delta": round(float((d * a).sum()) / 1e4, 3),
        "max_increase_kg_ha": round(float(max(0.0, d.max())), 3) if len(d) else 0.0,
        "max_decrease_kg_ha": round(float(max(0.0, -d.min())), 3) if len(d) else 0.0,
        "seq": [int(x) for x in np.asarray(seq)[changed][:max_listed]],
    }
