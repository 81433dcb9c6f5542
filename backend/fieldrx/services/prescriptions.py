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
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from fieldrx_edge.metering import calibration_from_dict
from geoalchemy2.shape import to_shape
from sqlalchemy import func, select, text
from sqlalchemy.orm import Session

from fieldrx.agronomy.cells import FLAG_BITS, CellTable, flag_names
from fieldrx.agronomy.interpolate import interpolate_to_cells
from fieldrx.agronomy.prescription import (
    ATTENTION_MASK,
    MODEL_INPUT,
    PrescriptionError,
    apply_cell_edits,
    build_prescription,
    paint_zone,
    summarize,
)
from fieldrx.agronomy.rates import MeterCheck, check_meter_range
from fieldrx.db.models import (
    Field,
    Machine,
    Plan,
    Prescription,
    PrescriptionRate,
    PrescriptionVersion,
    SoilSample,
)
from fieldrx.geo.crs import lonlat_to_utm_coords, lonlat_to_utm_xy, to_utm
from fieldrx.services import copy as pgcopy
from fieldrx.services.plans import driver_connection, load_cell_table, load_seq_area

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
    rows = session.execute(
        select(func.ST_X(SoilSample.geom), func.ST_Y(SoilSample.geom), col)
        .where(SoilSample.field_id == field_id, col.is_not(None))
        .order_by(SoilSample.id)
    ).all()
    if not rows:
        return np.zeros((0, 2)), np.zeros(0)
    a = np.asarray(rows, dtype=float)
    x, y = lonlat_to_utm_xy(a[:, 0], a[:, 1], epsg)
    return np.column_stack([x, y]), a[:, 2]


# --------------------------------------------------------------------------- rates COPY


def _flags_literal(mask: int, cache: dict[int, str]) -> str:
    s = cache.get(mask)
    if s is None:
        s = cache[mask] = "{" + ",".join(flag_names(mask)) + "}"
    return s


VARCHAR_OID = 1043


def _flags_array_bytes(mask: int) -> bytes:
    """Binary COPY form of a varchar[] holding the flag names of ``mask``."""
    names = [n.encode() for n in flag_names(mask)]
    if not names:
        return struct.pack(">iiI", 0, 0, VARCHAR_OID)
    body = struct.pack(">iiIii", 1, 0, VARCHAR_OID, len(names), 1)
    body += b"".join(struct.pack(">i", len(b)) + b for b in names)
    return body


def copy_rates(
    session: Session,
    version_id: int,
    seq: np.ndarray,
    rate_kg_ha: np.ndarray,
    flags: np.ndarray,
    source_value: np.ndarray | None,
) -> None:
    """All rates of one version with one binary COPY (in the session's transaction).

    Rows are grouped by (flag mask, source present): within a group every row
    has the same layout, so each group is one numpy structured array.
    """
    n = len(seq)
    src = np.full(n, np.nan) if source_value is None else np.asarray(source_value, float)
    has_src = ~np.isnan(src)
    masks = np.asarray(flags, np.int64)
    key = masks * 2 + has_src
    conn = driver_connection(session)
    with (
        conn.cursor() as cur,
        cur.copy(
            "COPY prescription_rates (version_id, seq, rate_kg_ha, source_value, flags) "
            "FROM STDIN (FORMAT BINARY)"
        ) as cp,
    ):
        cp.write(pgcopy.HEADER)
        for k in np.unique(key):
            rows = np.flatnonzero(key == k)
            fl = _flags_array_bytes(int(k) // 2)
            with_src = bool(k % 2)
            fields: list[tuple[str, Any]] = [
                ("nf", ">i2"),
                ("l_v", ">i4"),
                ("v", ">i4"),
                ("l_s", ">i4"),
                ("s", ">i4"),
                ("l_r", ">i4"),
                ("r", ">f8"),
                ("l_src", ">i4"),
            ]
            if with_src:
                fields.append(("src", ">f8"))
            fields += [("l_fl", ">i4"), ("fl", f"V{len(fl)}")]
            a = np.zeros(len(rows), dtype=np.dtype(fields))
            a["nf"] = 5
            a["l_v"], a["v"] = 4, version_id
            a["l_s"], a["s"] = 4, np.asarray(seq)[rows]
            a["l_r"], a["r"] = 8, np.asarray(rate_kg_ha, float)[rows]
            if with_src:
                a["l_src"], a["src"] = 8, src[rows]
            else:
                a["l_src"] = -1  # NULL
            a["l_fl"] = len(fl)
            a["fl"] = np.frombuffer(fl, dtype=f"V{len(fl)}")[0]
            cp.write(a.tobytes())
        cp.write(pgcopy.TRAILER)


_MASK_SQL = " | ".join(
    f"(CASE WHEN '{name}' = ANY(flags) THEN {bit} ELSE 0 END)" for name, bit in FLAG_BITS.items()
)
_RATES_SQL = f"""
SELECT string_agg(int4send(seq), ''::bytea), string_agg(float8send(rate_kg_ha), ''::bytea),
       string_agg(float8send(coalesce(source_value, 'NaN'::float8)), ''::bytea),
       string_agg(int4send({_MASK_SQL}), ''::bytea)
FROM (SELECT * FROM prescription_rates WHERE version_id = %s ORDER BY seq) r
"""


def load_rates(
    session: Session, version_id: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(seq, rate_kg_ha, flag bits, source_value) of one version in path order (packed fetch)."""
    conn = driver_connection(session)
    with conn.cursor(binary=True) as cur:
        cur.execute(_RATES_SQL, (version_id,))
        row = cur.fetchone()
    if row is None or row[0] is None:
        return np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.uint16), np.zeros(0)
    seq = np.frombuffer(bytes(row[0]), ">i4").astype(np.int64)
    rate = np.frombuffer(bytes(row[1]), ">f8").astype(float)
    src = np.frombuffer(bytes(row[2]), ">f8").astype(float)
    masks = np.frombuffer(bytes(row[3]), ">i4").astype(np.uint16)
    order = np.argsort(seq, kind="stable")
    if not np.array_equal(order, np.arange(len(seq))):
        seq, rate, src, masks = seq[order], rate[order], src[order], masks[order]
    return seq, rate, masks, src


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
    seq: np.ndarray,
    rates: np.ndarray,
    flags: np.ndarray,
    source: np.ndarray | None,
    summary: dict[str, Any],
) -> PrescriptionVersion:
    ver = PrescriptionVersion(
        prescription_id=rx.id, version=version, note=note, summary=summary, created_by=user_id
    )
    session.add(ver)
    session.flush()
    copy_rates(session, ver.id, seq, rates, flags, source)
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


def create_prescription(
    session: Session,
    plan: Plan,
    field: Field,
    *,
    name: str,
    product: str,
    model: str,
    params: dict[str, Any],
    interpolation: str,
    interpolation_params: dict[str, Any],
    fallback_rate_kg_ha: float | None,
    meter: MeterSpec | None,
    machine_id: int | None,
    user_id: int | None,
    organisation_id: int,
    cell_source: Callable[[CellTable], tuple[np.ndarray, dict[str, Any]]] | None = None,
    source: dict[str, Any] | None = None,
) -> Prescription:
    """Interpolate, rate, clamp and store version 1 (flush only). Raises ValueError subclasses.

    ``cell_source`` replaces the soil-sample interpolation: it gets the plan's cells and
    returns the model's per-cell input (NaN = no data) and a description for the summary
    (imagery NDVI uses it); ``source`` is recorded in the prescription's params.
    """
    model, params = canonical_model(model, params)
    if model not in MODEL_INPUT:
        raise RxError(f"unknown model {model!r} (expected one of {sorted(MODEL_INPUT)})")
    column = MODEL_INPUT[model]
    if column is None:  # uniform: no geometry needed
        seq, area = load_seq_area(session, plan)
        cells = None
    else:
        cells = load_cell_table(session, plan, field.utm_epsg)
        seq, area = cells.seq, cells.area_m2
    if len(seq) == 0:
        raise RxError(f"plan {plan.id} has no cells")
    check = None if meter is None else meter.check()
    values = no_data = None
    interp_info: dict[str, Any] | None = None
    if cells is not None and column is not None and cell_source is not None:
        values, interp_info = cell_source(cells)
        values = np.asarray(values, dtype=float)
        no_data = np.isnan(values)
        if no_data.all():
            raise RxError(f"the {model!r} input source has no data for any cell of plan {plan.id}")
    elif cells is not None and column is not None:
        xy, z = field_samples(session, field.id, column, field.utm_epsg)
        if len(z) == 0:
            what = "soil samples with n_mg_kg" if column == "n_mg_kg" else "samples with ndvi"
            raise RxError(
                f"model {model!r} needs {what} on field {field.id}: import them first "
                f"(POST /api/v1/fields/{field.id}/soil-samples)"
            )
        res = interpolate_to_cells(
            interpolation, cells.polygons_utm, cells.centroids_utm, xy, z, **interpolation_params
        )
        values, no_data = res.values, res.no_data
        interp_info = {"method": res.method, "n_samples": int(len(z)), **res.info}
    p = build_prescription(
        model,
        params,
        len(seq),
        values,
        no_data,
        check,
        fallback_rate_kg_ha,
        area,
    )
    summary = p.summary(area, seq=seq)
    if interp_info is not None:
        summary["interpolation"] = interp_info
    if meter is not None:
        summary["meter"] = meter.describe()
    summary = _json_safe(summary)
    rx = Prescription(
        organisation_id=organisation_id,
        plan_id=plan.id,
        machine_id=machine_id,
        name=name or f"{model} on plan {plan.id}",
        product=product,
        model=model,
        params={
            "model_params": params,
            "interpolation": None if column is None else interpolation,
            "interpolation_params": interpolation_params,
            "fallback_rate_kg_ha": fallback_rate_kg_ha,
            "meter": None if meter is None else meter.to_dict(),
            **({"source": source} if source else {}),
        },
        current_version=1,
    )
    session.add(rx)
    session.flush()
    _new_version(session, rx, 1, "created", user_id, seq, p.rate_kg_ha, p.flags, values, summary)
    return rx


def _meter_of(rx: Prescription) -> MeterCheck | None:
    m = (rx.params or {}).get("meter")
    return None if not m else MeterSpec(**m).check()


def cell_centroids_utm(session: Session, plan_id: int, epsg: int) -> tuple[np.ndarray, np.ndarray]:
    """(seq, UTM centroid) of every cell: what zone painting needs, without the polygons."""
    rows = session.execute(
        text(
            "SELECT seq, ST_X(p), ST_Y(p) FROM (SELECT seq, CASE WHEN ST_Within(ST_Centroid(geom),"
            " geom) THEN ST_Centroid(geom) ELSE ST_PointOnSurface(geom) END AS p "
            "FROM plan_cells WHERE plan_id = :p) s ORDER BY seq"
        ),
        {"p": plan_id},
    ).all()
    a = np.asarray(rows, dtype=float).reshape(-1, 3)
    return a[:, 0].astype(np.int64), lonlat_to_utm_coords(a[:, 1:], epsg)


def edit_prescription(
    session: Session,
    rx: Prescription,
    plan: Plan,
    field: Field,
    *,
    cells: list[tuple[int, float]] | None,
    zone: dict[str, Any] | None,
    zone_rate_kg_ha: float | None,
    note: str,
    user_id: int | None,
) -> tuple[PrescriptionVersion, int]:
    """Make version n+1 from the current version n (n is left as it is)."""
    from shapely.geometry import shape

    base = get_version(session, rx, None)
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
        cseq, cent = cell_centroids_utm(session, plan.id, field.utm_epsg)
        if not np.array_equal(cseq, seq):
            raise RxError("the plan's cells do not match the prescription's rates")
        new_rates, new_flags, changed = paint_zone(
            cent, rates, flags, zone_utm, zone_rate_kg_ha, meter
        )
        if changed == 0:
            raise RxError("the zone covers no cell centre of this plan")
    aseq, area = load_seq_area(session, plan)
    if not np.array_equal(aseq, seq):
        raise RxError("the plan's cells do not match the prescription's rates")
    summary = summarize(new_rates, new_flags, area, seq=seq)
    old = base.summary or {}
    for key in (
        "model",
        "params",
        "meter_range_kg_ha",
        "meter",
        "fallback_rate_kg_ha",
        "interpolation",
    ):
        if key in old:
            summary[key] = old[key]
    summary["edited_cells"] = int(changed)
    summary["based_on_version"] = base.version
    ver = _new_version(
        session,
        rx,
        _max_version(session, rx) + 1,
        note,
        user_id,
        seq,
        new_rates,
        new_flags,
        src,
        _json_safe(summary),
    )
    return ver, int(changed)


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
    rows = session.execute(
        text(
            "SELECT c.seq, c.swath, c.area_m2, r.rate_kg_ha, r.flags, r.source_value, "
            "ST_AsGeoJSON(c.geom, 9) FROM plan_cells c JOIN prescription_rates r "
            "ON r.version_id = :v AND r.seq = c.seq "
            "WHERE c.plan_id = :p AND c.seq >= :a AND c.seq < :b ORDER BY c.seq"
        ),
        {"p": plan_id, "v": version_id, "a": offset, "b": offset + limit},
    )
    out = []
    for seq, swath, area, rate, flags, src, gj in rows:
        fl = list(flags or [])
        out.append(
            {
                "type": "Feature",
                "id": seq,
                "geometry": json.loads(gj),
                "properties": {
                    "seq": seq,
                    "swath": swath,
                    "area_m2": round(area, 3),
                    "rate_kg_ha": rate,
                    "flags": fl,
                    # outside what the machine meters at the planned speeds (stored as asked)
                    "out_of_meter_range": "below_meter_range" in fl or "above_meter_range" in fl,
                    # no sample near enough: the rate is the prescription's fallback rate
                    "fallback": "no_data" in fl,
                    "source_value": src,
                },
            }
        )
    return out


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
    aseq, area = load_seq_area(session, plan)
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
        "seq": [int(x) for x in seq[mask][:50]],
        "meter": spec.describe(),
    }


def version_cells(session: Session, rx: Prescription, ver: PrescriptionVersion) -> CellTable:
    """The plan's cells with this version's rates and flags (for exports / job packages)."""
    plan = session.get(Plan, rx.plan_id)
    field = session.get(Field, plan.field_id) if plan is not None else None
    if plan is None or field is None:
        raise LookupError(f"prescription {rx.id}: plan or field is gone")
    cells = load_cell_table(session, plan, field.utm_epsg)
    seq, rates, flags, _ = load_rates(session, ver.id)
    if not np.array_equal(seq, cells.seq):
        raise RxError("the plan's cells do not match the prescription's rates")
    return cells.with_rates(rates, flags)


def field_boundary_wgs84(session: Session, rx: Prescription) -> Any:
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
