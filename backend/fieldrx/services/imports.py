"""Store an ISOXML import: farms, fields, a plan per prescribed field and prescription versions.

``preview`` validates everything the upload would create (boundaries like any
field, ``geo.validate``) and lists it with what is skipped; ``commit`` does
the same inside the request's transaction and flushes, so a failure anywhere
leaves nothing behind (the API commits once at the end).

An imported prescription needs FieldRx cells: a plan is built on the field
with the caller's plan parameters, and each cell takes the imported rate:

* grids: the most common rate of the grid cells whose centres fall in the
  cell (a FieldRx grid export assigns each grid centre the rate of the cell
  under it, so this gives each cell back its own rate); a cell no grid centre
  falls in takes the rate at its inside point;
* zones: the rate of the zone its inside point lies in, the task's default
  zone (TSK H) elsewhere.

The version's summary records the source (file, task, DDI, unit, kind).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from sqlalchemy.orm import Session

from fieldrx.agronomy.cells import CellTable
from fieldrx.agronomy.prescription import planned_kg, summarize
from fieldrx.agronomy.products import product_figures
from fieldrx.db.geometry import shape_to_db
from fieldrx.db.models import Farm, Field, Plan, Prescription, PrescriptionVersion
from fieldrx.db.session import limit_session
from fieldrx.formats import FormatError
from fieldrx.formats.archive import read_zip
from fieldrx.formats.isoxml_import import RxIn, TaskDataSet, read_taskdata
from fieldrx.geo import PlanningError
from fieldrx.geo.crs import to_utm
from fieldrx.geo.validate import BoundaryError, validate_boundary
from fieldrx.services.import_checks import match_farm, match_field, placement
from fieldrx.services.plans import PlanParams, check_plan_cost, create_plan
from fieldrx.services.prescriptions.classes import auto_classes
from fieldrx.store import load_cells, write_rates

IMPORTED_MODEL = "imported"
# the implement type of the machines an import creates to hold other terminals' logs:
# they never receive a job (not listed as sendable, refused by POST /jobs)
IMPORTED_IMPLEMENT = "imported"


Stage = Callable[[float, str], None]


def _validated(ds: TaskDataSet) -> list[Any]:
    """Each partfield's validated boundary; one that fails validation is dropped from
    the set and named in its skipped list (the others still import), unless none is left."""
    out = []
    keep = []
    reasons = []
    for f in ds.fields:
        try:
            out.append(validate_boundary(shapely.geometry.mapping(f.boundary)))
            keep.append(f)
        except BoundaryError as exc:
            msg = f"partfield {f.ref} ({f.name}): {exc}"
            ds.skip(f"PFD[{f.ref}] {f.name}", f"refused: {msg}", bad=True)
            reasons.append(msg)
    if reasons and not keep:
        raise FormatError("; ".join(reasons))
    refs = {f.ref for f in keep}
    for rx in [r for r in ds.prescriptions if r.field_ref not in refs]:
        ds.prescriptions.remove(rx)
        ds.skip(f"TSK[{rx.ref}] {rx.name}", f"its partfield {rx.field_ref} was refused")
    ds.fields[:] = keep
    return out


def _placed(ds: TaskDataSet, valid: list[Any]) -> dict[str, dict[str, Any]]:
    """Where each prescription's data lies on its field; data off the field is dropped
    from the set and named (with its distance) in the skipped list."""
    by_ref = {f.ref: (f, v) for f, v in zip(ds.fields, valid, strict=True)}
    out: dict[str, dict[str, Any]] = {}
    for rx in list(ds.prescriptions):
        f, v = by_ref[rx.field_ref]
        pl = placement(v.geometry, v.utm_epsg, rx.coverage())
        what = f"{rx.kind} of task {rx.ref} ({rx.name})"
        note = pl.describe(what, f.name)
        out[rx.ref] = {"overlap_pct": pl.overlap_pct, "distance_m": round(pl.distance_m, 1)}
        if note:
            out[rx.ref]["warning"] = note
        if pl.refused:
            ds.prescriptions.remove(rx)
            ds.skip(f"TSK[{rx.ref}] {rx.name}", note or "", bad=True)
    return out


def _rx_preview(r: RxIn, place: dict[str, Any]) -> dict[str, Any]:
    rates = r.grid["rates"] if r.grid is not None else np.asarray([z for z, _ in r.zones])
    return {
        "ref": r.ref,
        "name": r.name,
        "field_ref": r.field_ref,
        "kind": r.kind,
        "ddi": r.ddi,
        "unit": r.unit,
        "density_kg_l": r.density_kg_l,
        "product": r.product,
        "default_rate_kg_ha": r.default_rate_kg_ha,
        "min_rate_kg_ha": round(float(np.min(rates)), 2) if rates.size else None,
        "max_rate_kg_ha": round(float(np.max(rates)), 2) if rates.size else None,
        "zones": len(r.zones) if r.grid is None else None,
        "grid": None
        if r.grid is None
        else {"rows": int(r.grid["rates"].shape[0]), "cols": int(r.grid["rates"].shape[1])},
        "extent": [round(x, 7) for x in r.coverage().bounds],
        "note": None if r.grid is None else r.grid.get("note"),
        **place,
    }


def _matches(
    session: Session, ds: TaskDataSet, valid: list[Any], organisation_id: int
) -> tuple[dict[str, Farm], dict[str, tuple[Field, str]]]:
    farms: dict[str, Farm] = {}
    for fa in ds.farms:
        farm_row = match_farm(session, organisation_id, fa.name)
        if farm_row is not None:
            farms[fa.ref] = farm_row
    fields: dict[str, tuple[Field, str]] = {}
    for f, v in zip(ds.fields, valid, strict=True):
        row, by = match_field(session, organisation_id, f.ref, f.name, v.geometry, v.utm_epsg)
        if row is not None:
            fields[f.ref] = (row, by)
    return farms, fields


def preview(session: Session, ds: TaskDataSet, organisation_id: int) -> dict[str, Any]:
    """What a confirmed import creates, matches and skips (nothing is stored)."""
    valid = _validated(ds)
    place = _placed(ds, valid)
    farms, fields = _matches(session, ds, valid, organisation_id)
    return {
        "version": ds.version,
        "farms": [
            {
                "ref": f.ref,
                "name": f.name,
                "match": None
                if f.ref not in farms
                else {"id": farms[f.ref].id, "name": farms[f.ref].name, "by": "name"},
            }
            for f in ds.farms
        ],
        "fields": [
            {
                "ref": f.ref,
                "name": f.name,
                "farm_ref": f.farm_ref,
                "area_m2": round(v.area_m2, 2),
                "declared_area_m2": f.declared_area_m2,
                "holes": sum(len(p.interiors) for p in getattr(f.boundary, "geoms", [f.boundary])),
                "parts": len(getattr(f.boundary, "geoms", [f.boundary])),
                "features": _feature_counts(f.features),
                "centre": [round(c, 7) for c in v.geometry.representative_point().coords[0]],
                "match": None
                if f.ref not in fields
                else {
                    "id": fields[f.ref][0].id,
                    "name": fields[f.ref][0].name,
                    "by": fields[f.ref][1],
                },
            }
            for f, v in zip(ds.fields, valid, strict=True)
        ],
        "prescriptions": [_rx_preview(r, place[r.ref]) for r in ds.prescriptions],
        "timelogs": ds.timelogs,
        "skipped": ds.skipped,
        "bad": [s for s in ds.skipped if s.get("bad")],
    }


def _feature_counts(features: list[dict[str, Any]]) -> dict[str, int]:
    out: dict[str, int] = {}
    for f in features:
        key = f"{f['properties']['kind']}: {f['properties']['type']}"
        out[key] = out.get(key, 0) + 1
    return out


def cell_rates(rx: RxIn, cells: CellTable) -> np.ndarray:
    """Imported rate per FieldRx cell (see module docstring)."""
    polys = cells.polygons_wgs84()
    inside = shapely.get_coordinates(shapely.point_on_surface(polys))
    rates = rx.rates_at(inside[:, 0], inside[:, 1])
    centres = rx.grid_centres()
    if centres is not None:
        lon, lat, val = centres
        tree = shapely.STRtree(polys)
        pi, ci = tree.query(shapely.points(lon, lat), predicate="intersects")
        if len(pi):
            v = np.rint(val[pi] * 100.0).astype(np.int64)
            key = np.lexsort((v, ci))
            ci, v = ci[key], v[key]
            # per cell: the value with the longest run (mode) in the sorted pairs
            new = np.ones(len(ci), dtype=bool)
            new[1:] = (ci[1:] != ci[:-1]) | (v[1:] != v[:-1])
            starts = np.flatnonzero(new)
            counts = np.diff(np.append(starts, len(ci)))
            run_cell, run_val = ci[starts], v[starts]
            order = np.lexsort((-counts, run_cell))
            run_cell, run_val = run_cell[order], run_val[order]
            first = np.ones(len(run_cell), dtype=bool)
            first[1:] = run_cell[1:] != run_cell[:-1]
            rates[run_cell[first]] = run_val[first] / 100.0
    return np.round(rates, 2)


def outside_share(rx: RxIn, cells: CellTable) -> dict[str, Any]:
    """How much of the imported data falls outside the plan's cells: for zones the
    share of their area, for grids the share of grid cells with a rate above 0 whose
    centre lies in no plan cell (product the plan cannot place)."""
    cover = shapely.union_all(cells.polygons_wgs84())
    centres = rx.grid_centres()
    if centres is not None:
        lon, lat, val = centres
        live = val > 0
        if not live.any():
            return {"share_pct": 0.0, "of": "grid cells with a rate"}
        inside = shapely.intersects(cover, shapely.points(lon[live], lat[live]))
        share = 100.0 * float((~inside).sum()) / float(live.sum())
        return {"share_pct": round(share, 2), "of": "grid cells with a rate"}
    z = to_utm(shapely.union_all([p for _, p in rx.zones]), cells.epsg)
    out = z.difference(shapely.union_all(cells.polygons_utm)).area
    return {"share_pct": round(100.0 * out / max(z.area, 1e-9), 2), "of": "zone area"}


def store_prescription(
    session: Session,
    rx: RxIn,
    fld: Field,
    params: PlanParams,
    organisation_id: int,
    user_id: int | None,
    source: dict[str, Any],
) -> tuple[Prescription, Plan]:
    """A plan on ``fld`` and version 1 of an imported prescription on it (flush only)."""
    plan = create_plan(session, fld, params, organisation_id)
    cells = load_cells(session, plan.id, fld.utm_epsg)
    rates = cell_rates(rx, cells)
    row = Prescription(
        organisation_id=organisation_id,
        plan_id=plan.id,
        name=rx.name[:200],
        product=rx.product or "fertilizer",
        model=IMPORTED_MODEL,
        params={"imported": source},
        current_version=1,
    )
    session.add(row)
    session.flush()
    area = np.asarray(cells.area_m2, dtype=float)
    flags = np.zeros(len(cells), np.uint16)
    # the same figures, legend classes and zones table as a computed prescription's
    summary = summarize(rates, flags, area, seq=cells.seq)
    summary.update(product_figures(rates, area, None))
    summary["classes"] = auto_classes(rates, area, 6)
    summary.update(
        {
            "source": source,
            "min_rate_kg_ha": float(rates.min(initial=0.0)),
            "max_rate_kg_ha": float(rates.max(initial=0.0)),
            "mean_rate_kg_ha": float(np.sum(rates * area) / max(area.sum(), 1e-12)),
            "total_kg": planned_kg(rates, area),
            "extent": list(shapely.union_all(cells.polygons_wgs84()).bounds),
            "imported_outside": outside_share(rx, cells),
        }
    )
    ver = PrescriptionVersion(
        prescription_id=row.id, version=1, note="imported", summary=summary, created_by=user_id
    )
    session.add(ver)
    session.flush()
    write_rates(session, ver.id, cells.seq, rates, flags, None)
    return row, plan


def commit(
    session: Session,
    ds: TaskDataSet,
    organisation_id: int,
    user_id: int | None,
    params: PlanParams,
    source_name: str,
    progress: Stage | None = None,
) -> dict[str, Any]:
    """Create everything (flush only; the caller commits once). Returns the new ids.
    ``progress(share, message)`` hears of each prescription planned (the long part).

    Farms and fields that already exist (``import_checks``) are used, not created again."""
    valid = _validated(ds)
    _placed(ds, valid)
    old_farms, old_fields = _matches(session, ds, valid, organisation_id)
    farm_ids: dict[str, int] = {ref: row.id for ref, row in old_farms.items()}
    new_farms = []
    for farm_in in ds.farms:
        if farm_in.ref in farm_ids:
            continue
        farm = Farm(
            organisation_id=organisation_id, name=farm_in.name[:200], notes="imported from ISOXML"
        )
        session.add(farm)
        session.flush()
        farm_ids[farm_in.ref] = farm.id
        new_farms.append(farm.id)
    fields: dict[str, Field] = {}
    created = []
    for f, v in zip(ds.fields, valid, strict=True):
        if f.ref in old_fields:
            fields[f.ref] = old_fields[f.ref][0]
            continue
        row = Field(
            organisation_id=organisation_id,
            farm_id=farm_ids.get(f.farm_ref or ""),
            name=f.name[:200],
            crop="",
            notes=f"imported from ISOXML partfield {f.ref}",
            boundary=shape_to_db(v.geometry),
            utm_epsg=v.utm_epsg,
            area_m2=v.area_m2,
            source_ref=f"ISOXML {f.ref}"[:200],
            features=f.features,
        )
        session.add(row)
        session.flush()
        fields[f.ref] = row
        created.append(f.ref)
    created_rx = []
    for i, rx in enumerate(ds.prescriptions):
        if progress is not None:
            progress(
                i / len(ds.prescriptions),
                f"planning and storing prescription {i + 1} of {len(ds.prescriptions)} ({rx.name})",
            )
        fld = fields[rx.field_ref]
        source = {
            "file": source_name,
            "task": rx.ref,
            "kind": rx.kind,
            "ddi": rx.ddi,
            "unit": rx.unit,
            "density_kg_l": rx.density_kg_l,
            "isoxml_version": ds.version,
        }
        rx_row, plan = store_prescription(
            session, rx, fld, params, organisation_id, user_id, source
        )
        created_rx.append({"id": rx_row.id, "plan_id": plan.id, "field_id": fld.id, "ref": rx.ref})
    return {
        "farms": sorted(new_farms),
        "fields": [{"id": fields[r].id, "ref": r, "name": fields[r].name} for r in created],
        "matched_farms": sorted({row.id for row in old_farms.values()}),
        "matched_fields": [
            {"id": row.id, "ref": ref, "name": row.name, "by": by}
            for ref, (row, by) in old_fields.items()
        ],
        "prescriptions": created_rx,
        "skipped": [s for s in ds.skipped if s.get("bad")],
    }


@dataclass
class IsoxmlRequest:
    """One ISOXML import for ``isoxml_in_worker``: the spooled files (name, path), and for
    a confirm the plan parameters and who stores it."""

    database_url: str
    files: list[tuple[str, str]]
    source_name: str
    organisation_id: int
    user_id: int | None
    params: PlanParams
    confirm: bool = False
    time_limit_s: float = 120.0
    density_kg_l: float | None = None


def read_spooled(files: list[tuple[str, str]]) -> dict[str, bytes]:
    out: dict[str, bytes] = {}
    for name, path in files:
        if name.lower().endswith(".zip"):
            try:
                out.update(read_zip(path))
            except FormatError as exc:
                raise FormatError(f"{name}: {exc}") from exc
        else:
            out[name] = Path(path).read_bytes()
    return out


def check_import_cost(ds: TaskDataSet, params: PlanParams) -> None:
    """The plan cost estimate (``services.plans.check_plan_cost``) of every field a
    confirmed import would plan, before anything is stored or planned."""
    areas = {f.ref: v.area_m2 for f, v in zip(ds.fields, _validated(ds), strict=True)}
    for rx in ds.prescriptions:
        try:
            check_plan_cost(areas[rx.field_ref], params)
        except PlanningError as exc:
            raise PlanningError(f"task {rx.ref} (partfield {rx.field_ref}): {exc}") from exc


def _scaled(progress: Stage, lo: float, hi: float) -> Stage:
    return lambda share, message: progress(lo + (hi - lo) * share, message)


def confirm_isoxml(session: Session, req: IsoxmlRequest, progress: Stage) -> dict[str, Any]:
    """Read, preview, check and store a spooled TASKDATA upload in the session's
    transaction (flush only: the caller commits once, so a failure stores nothing).
    Returns ``{"preview", "created"}``; ``progress`` hears the stages."""
    mb = sum(Path(path).stat().st_size for _, path in req.files) / 1024**2
    progress(0.02, f"inflating and reading {mb:,.1f} MB of TASKDATA")
    ds = read_taskdata(read_spooled(req.files), req.density_kg_l)
    progress(0.15, f"checking {len(ds.fields)} field(s) against the farm's data")
    pre = preview(session, ds, req.organisation_id)
    check_import_cost(ds, req.params)
    progress(0.25, f"storing {len(ds.fields)} field(s)")
    created = commit(
        session,
        ds,
        req.organisation_id,
        req.user_id,
        req.params,
        req.source_name,
        progress=_scaled(progress, 0.3, 0.95),
    )
    return {"preview": pre, "created": created}


def isoxml_in_worker(req: IsoxmlRequest) -> dict[str, Any]:
    """Inflate, parse and preview a spooled TASKDATA upload and, on confirm, store it and
    commit, all in a ``services.bounded`` child (the archive never inflates in the server's
    memory; planning runs under the time limit). Returns ``{"preview", "created"?}``."""
    from fieldrx.db.session import make_engine
    from fieldrx.services.bounded import ensure_caller_alive

    engine = make_engine(req.database_url)
    try:
        with Session(engine) as session:
            limit_session(session, req.time_limit_s)
            if not req.confirm:
                ds = read_taskdata(read_spooled(req.files), req.density_kg_l)
                return {"preview": preview(session, ds, req.organisation_id)}
            out = confirm_isoxml(session, req, lambda share, message: None)
            ensure_caller_alive("the ISOXML import")
            session.commit()
            return out
    finally:
        engine.dispose()


@dataclass
class RxStoreRequest:
    """An imported prescription to store on a field by ``store_prescription_in_worker``."""

    database_url: str
    rx: RxIn
    field_id: int
    params: PlanParams
    organisation_id: int
    user_id: int | None
    source: dict[str, Any]
    time_limit_s: float = 120.0


def store_prescription_in_worker(req: RxStoreRequest) -> tuple[int, int]:
    """``store_prescription`` and commit in a ``services.bounded`` child (its plan is
    planned under the time limit, never in the request thread); returns (rx id, plan id)."""
    from fieldrx.db.session import make_engine
    from fieldrx.services.bounded import ensure_caller_alive

    engine = make_engine(req.database_url)
    try:
        with Session(engine) as session:
            limit_session(session, req.time_limit_s)
            fld = session.get(Field, req.field_id)
            if fld is None:
                raise PlanningError(f"field {req.field_id} was deleted while importing")
            row, plan = store_prescription(
                session, req.rx, fld, req.params, req.organisation_id, req.user_id, req.source
            )
            ids = (int(row.id), int(plan.id))
            ensure_caller_alive("the prescription import")
            session.commit()
    finally:
        engine.dispose()
    return ids
