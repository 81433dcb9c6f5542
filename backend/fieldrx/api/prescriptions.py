"""Prescriptions: build from a plan + soil data, versions, cells, edits, exports."""

from __future__ import annotations

import json
from typing import Any, Literal

from fastapi import APIRouter, Query
from fastapi.responses import Response
from sqlalchemy import select

from fieldrx.agronomy.interpolate import InterpolationError
from fieldrx.agronomy.prescription import PrescriptionError
from fieldrx.agronomy.ratemodels.registry import RateModelError
from fieldrx.agronomy.rates import MeterRangeError
from fieldrx.agronomy.zones import ZoneError
from fieldrx.api.common import ApiError, get_scoped
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.files import file_response
from fieldrx.api.schemas.formats import RxExportFormat
from fieldrx.api.schemas.prescriptions import (
    CurrentIn,
    EditIn,
    EditOut,
    PrescriptionIn,
    PrescriptionList,
    PrescriptionOut,
    RxCellPage,
    SoilZonesIn,
    VersionDetail,
    VersionDiff,
    VersionList,
    VersionPatch,
)
from fieldrx.api.schemas.tasks import QUEUED
from fieldrx.auth.deps import Principal, SessionDep, UserDep, WriterDep
from fieldrx.db.models import Field as FieldRow
from fieldrx.db.models import Machine, Plan, Prescription, PrescriptionVersion
from fieldrx.formats import FormatError
from fieldrx.services import exports
from fieldrx.services.evidence import delete_jobs, refuse_if_evidence
from fieldrx.services.prescriptions import create as rx_create
from fieldrx.services.prescriptions import edits as rx_edits
from fieldrx.services.prescriptions import params as rx_params
from fieldrx.services.prescriptions import samples as rx_samples
from fieldrx.services.prescriptions import versions as rx_versions

router = APIRouter(tags=["prescriptions"], responses=ERRORS)

MAX_PAGE = 50_000
BAD_INPUT = (
    FormatError,
    rx_params.RxError,
    PrescriptionError,
    RateModelError,
    MeterRangeError,
    InterpolationError,
)


def _plan_field(session: SessionDep, plan: Plan) -> FieldRow:
    field = session.get(FieldRow, plan.field_id)
    assert field is not None
    return field


def _body_machine(
    session: SessionDep, body: PrescriptionIn, principal: Principal
) -> Machine | None:
    """The body's machine (its meter range and calibration), the organisation's own or 422."""
    if body.machine_id is None:
        return None
    machine = session.get(Machine, body.machine_id)
    if machine is None or machine.organisation_id != principal.organisation_id:
        raise ApiError(422, f"machine {body.machine_id} not found", where="machine_id")
    return machine


def _store(
    session: SessionDep,
    plan: Plan,
    field: FieldRow,
    machine: Machine | None,
    body: PrescriptionIn,
    principal: Principal,
    name: str,
    errors: tuple[type[Exception], ...] = BAD_INPUT,
    **extra: Any,
) -> dict[str, Any]:
    """Build and store version 1 from ``body`` (one transaction; bad input: 422, nothing
    stored); ``extra`` goes to ``create_prescription`` (a cell source, its description)."""
    try:
        rx = rx_create.create_from_request(
            session,
            plan,
            field,
            machine,
            body.model_dump(),
            organisation_id=principal.organisation_id,
            user_id=principal.user_id,
            name=name,
            **extra,
        )
    except errors as exc:
        session.rollback()
        raise ApiError(422, str(exc)) from exc
    session.commit()
    return rx_versions.prescription_summary(session, rx)


@router.post(
    "/plans/{plan_id:int}/prescriptions",
    status_code=201,
    response_model=PrescriptionOut,
    responses=QUEUED,
)
def create(
    plan_id: int,
    body: PrescriptionIn,
    principal: WriterDep,
    session: SessionDep,
    background: bool = Query(
        default=False,
        description="queue the work for a `fieldrx worker` and answer 202 with the task",
    ),
) -> Any:
    """Interpolate the field's samples onto the plan's cells, apply the rate model, clamp to
    the metering range (flagged), and store version 1. With ``background=true`` it is
    queued instead (202 with the task; its ``result_url`` is the prescription)."""
    plan = get_scoped(session, Plan, plan_id, principal)
    field = _plan_field(session, plan)
    machine = _body_machine(session, body, principal)
    if background:
        from fieldrx.api.tasks import queue_task

        return queue_task(
            session,
            principal,
            "prescription",
            {"plan_id": plan.id, "body": body.model_dump(mode="json")},
        )
    return _store(session, plan, field, machine, body, principal, name=body.name)


@router.post("/plans/{plan_id:int}/zones", status_code=201, response_model=PrescriptionOut)
def create_soil_zones(
    plan_id: int, body: SoilZonesIn, principal: WriterDep, session: SessionDep
) -> dict:
    """Management zones from soil samples: the model's input (nutrient_balance: n_mg_kg,
    ndvi: sample NDVI) interpolated onto the plan's cells (``interpolation``), k-means into
    ``k`` zones (zone 1 lowest), patches under ``min_area_m2`` merged into their main
    neighbour, and one rate per zone: the model at the zone's area-weighted mean. Stored as
    version 1 of a prescription (edits, ISOXML treatment zones, Shapefile as usual); the
    zone table is in ``summary.interpolation.zones``."""
    plan = get_scoped(session, Plan, plan_id, principal)
    field = _plan_field(session, plan)
    machine = _body_machine(session, body, principal)
    try:
        source = rx_samples.soil_zone_source(
            session,
            field,
            body.model,
            body.interpolation,
            body.interpolation_params,
            body.k,
            body.min_area_m2,
        )
    except BAD_INPUT as exc:
        raise ApiError(422, str(exc)) from exc
    return _store(
        session,
        plan,
        field,
        machine,
        body,
        principal,
        name=body.name or f"{body.k} soil zones ({body.model}) on plan {plan.id}",
        errors=(*BAD_INPUT, ZoneError),
        cell_source=source,
        source={
            "zones": {
                "from": "soil_samples",
                "k": body.k,
                "min_area_m2": body.min_area_m2,
                "classifier": "kmeans_1d",
            }
        },
    )


@router.get("/prescriptions", response_model=PrescriptionList)
def list_prescriptions(
    principal: UserDep, session: SessionDep, plan_id: int | None = None
) -> dict[str, Any]:
    stmt = select(Prescription).where(Prescription.organisation_id == principal.organisation_id)
    if plan_id is not None:
        stmt = stmt.where(Prescription.plan_id == plan_id)
    rows = session.scalars(stmt.order_by(Prescription.id)).all()
    items = [rx_versions.prescription_summary(session, r) for r in rows]
    return {"items": items, "total": len(rows)}


@router.get("/prescriptions/{rx_id:int}", response_model=PrescriptionOut)
def get_prescription(rx_id: int, principal: UserDep, session: SessionDep) -> dict[str, Any]:
    """Current version's summary: area, product mass, mean/min/max, histogram, flags, CV RMSE."""
    rx = get_scoped(session, Prescription, rx_id, principal)
    return rx_versions.prescription_summary(session, rx)


def _version(session: SessionDep, rx: Prescription, version: int | None) -> PrescriptionVersion:
    try:
        return rx_versions.get_version(session, rx, version)
    except LookupError as exc:
        raise ApiError(404, str(exc)) from exc


@router.get("/prescriptions/{rx_id:int}/versions", response_model=VersionList)
def list_versions(rx_id: int, principal: UserDep, session: SessionDep) -> dict[str, Any]:
    rx = get_scoped(session, Prescription, rx_id, principal)
    rows = session.scalars(
        select(PrescriptionVersion)
        .where(PrescriptionVersion.prescription_id == rx.id)
        .order_by(PrescriptionVersion.version)
    ).all()
    return {
        "items": [rx_versions.version_summary(v) for v in rows],
        "total": len(rows),
        "current_version": rx.current_version,
    }


@router.get("/prescriptions/{rx_id:int}/versions/{version:int}", response_model=VersionDetail)
def get_version(rx_id: int, version: int, principal: UserDep, session: SessionDep) -> dict:
    rx = get_scoped(session, Prescription, rx_id, principal)
    return {"prescription_id": rx.id, **rx_versions.version_summary(_version(session, rx, version))}


@router.patch("/prescriptions/{rx_id:int}/versions/{version:int}", response_model=VersionDetail)
def patch_version(
    rx_id: int, version: int, body: VersionPatch, principal: WriterDep, session: SessionDep
) -> dict:
    """A version's note and its legend classes (``class_count`` equal classes or explicit
    ``breaks_kg_ha``); the zones table follows. Its rates never change."""
    rx = get_scoped(session, Prescription, rx_id, principal)
    ver = _version(session, rx, version)
    try:
        rx_edits.patch_version(
            session,
            rx,
            ver,
            note=body.note,
            class_count=body.class_count,
            breaks_kg_ha=body.breaks_kg_ha,
        )
    except BAD_INPUT as exc:
        session.rollback()
        raise ApiError(422, str(exc), where="breaks_kg_ha") from exc
    session.commit()
    return {"prescription_id": rx.id, **rx_versions.version_summary(ver)}


@router.put("/prescriptions/{rx_id:int}/current", response_model=PrescriptionOut)
def set_current(
    rx_id: int, body: CurrentIn, principal: WriterDep, session: SessionDep
) -> dict[str, Any]:
    """Make an existing version current: undo goes back to the version an edit was made
    from, redo forward to the edit's version. No version is changed or deleted."""
    rx = get_scoped(session, Prescription, rx_id, principal)
    try:
        rx_versions.set_current(session, rx, body.version)
    except LookupError as exc:
        raise ApiError(404, str(exc), where="version") from exc
    session.commit()
    return rx_versions.prescription_summary(session, rx)


@router.get("/prescriptions/{rx_id:int}/diff", response_model=VersionDiff)
def diff(
    rx_id: int,
    principal: UserDep,
    session: SessionDep,
    from_version: int = Query(ge=1, alias="from"),
    to_version: int = Query(ge=1, alias="to"),
) -> dict[str, Any]:
    """Version ``to`` minus version ``from``: cells and area whose rate changed, product
    (kg) and cost delta, mean rate delta, largest increase / decrease, changed cells."""
    rx = get_scoped(session, Prescription, rx_id, principal)
    va, vb = _version(session, rx, from_version), _version(session, rx, to_version)
    try:
        return rx_versions.diff_versions(session, rx, va, vb)
    except BAD_INPUT as exc:
        raise ApiError(422, str(exc)) from exc


@router.get("/prescriptions/{rx_id:int}/cells", response_model=RxCellPage)
def get_cells(
    rx_id: int,
    principal: UserDep,
    session: SessionDep,
    version: int | None = None,
    limit: int = Query(default=1000, ge=1, le=MAX_PAGE),
    offset: int = Query(default=0, ge=0),
) -> dict[str, Any]:
    """Cells of a version (default: current) with rate_kg_ha, flags, source_value; paged."""
    rx = get_scoped(session, Prescription, rx_id, principal)
    ver = _version(session, rx, version)
    plan = session.get(Plan, rx.plan_id)
    assert plan is not None
    return {
        "type": "FeatureCollection",
        "features": rx_versions.rates_page(session, plan.id, ver.id, limit, offset),
        "total": plan.n_cells,
        "version": ver.version,
        "limit": limit,
        "offset": offset,
    }


@router.post("/prescriptions/{rx_id:int}/edits", status_code=201, response_model=EditOut)
def edit(rx_id: int, body: EditIn, principal: WriterDep, session: SessionDep) -> dict[str, Any]:
    """Per-cell rates or a painted zone -> version n+1 (n unchanged). Edited rates are
    meter-checked; cells are flagged manual (cells) or zone (zone)."""
    rx = get_scoped(session, Prescription, rx_id, principal)
    plan = session.get(Plan, rx.plan_id)
    assert plan is not None
    try:
        ver, changed = rx_edits.edit_prescription(
            session,
            rx,
            plan,
            _plan_field(session, plan),
            rx_edits.RateEdit(
                cells=None if body.cells is None else [(c.seq, c.rate_kg_ha) for c in body.cells],
                zone=body.zone,
                zone_rate_kg_ha=body.rate_kg_ha,
            ),
            note=body.note,
            user_id=principal.user_id,
            based_on=body.based_on_version,
        )
    except LookupError as exc:
        session.rollback()
        raise ApiError(404, str(exc), where="based_on_version") from exc
    except BAD_INPUT as exc:
        session.rollback()
        raise ApiError(422, str(exc)) from exc
    session.commit()
    out = rx_versions.prescription_summary(session, rx)
    out["edited_cells"] = changed
    out["new_version"] = ver.version
    return out


@router.get(
    "/prescriptions/{rx_id:int}/export",
    response_class=Response,
    responses={
        **file_response(
            "the version as a file (Content-Disposition names it)",
            "application/geo+json",
            "text/csv",
            "application/zip",
        ),
        **QUEUED,
    },
)
def export(
    rx_id: int,
    principal: UserDep,
    session: SessionDep,
    format: RxExportFormat = "geojson",
    version: int | None = None,
    profile: Literal["cells", "deere", "fieldview", "raven", "agleader", "trimble"] = "cells",
    zone_classes: int | None = Query(default=None, ge=1, le=254),
    max_polygons: int | None = Query(default=None, ge=1, le=100_000),
    background: bool | None = Query(
        default=None,
        description="true: write the file in a task (202 with it; its result_url downloads "
        "it); false: inline; unset: a task above FIELDRX_EXPORT_BACKGROUND_CELLS cells",
    ),
) -> Response:
    """One version as a file download (GeoJSON, Table 1 CSV, zipped Shapefile, TASKDATA.zip).

    ``profile`` (Shapefile) picks a terminal layout; zone exports (profiles
    other than ``cells`` and ``isoxml-zones``) dissolve cells into
    ``zone_classes`` rate classes within ``max_polygons``, and say how in the
    ``X-FieldRx-Export-Note`` header (area moved, largest rate change).
    """
    rx = get_scoped(session, Prescription, rx_id, principal)
    ver = _version(session, rx, version)
    if background or (background is None and _large_export(session, rx)):
        from fieldrx.api.tasks import queue_task

        params = {
            "source": "prescription",
            "rx_id": rx.id,
            "version": ver.version,
            "format": format,
            "profile": profile,
            "zone_classes": zone_classes,
            "max_polygons": max_polygons,
        }
        return queue_task(session, principal, "export", params)
    info: dict[str, Any] = {}
    try:
        data, media, filename = exports.export_version(
            session,
            rx,
            ver,
            format,
            profile=profile,
            zone_classes=zone_classes,
            max_polygons=max_polygons,
            info=info,
        )
    except BAD_INPUT as exc:
        raise ApiError(422, str(exc)) from exc
    headers = {
        "Content-Disposition": f'attachment; filename="{filename}"',
        "ETag": f'"rx-{ver.id}-{format}-{profile}-{zone_classes}-{max_polygons}"',
    }
    if "note" in info:
        headers["X-FieldRx-Export-Note"] = info["note"]
        headers["X-FieldRx-Zones"] = json.dumps(info["zones"], separators=(",", ":"))
    return Response(content=data, media_type=media, headers=headers)


def _large_export(session: SessionDep, rx: Prescription) -> bool:
    from fieldrx.settings import get_settings

    plan = session.get(Plan, rx.plan_id)
    return plan is not None and plan.n_cells > get_settings().export_background_cells


@router.delete("/prescriptions/{rx_id:int}", status_code=204)
def delete(rx_id: int, principal: WriterDep, session: SessionDep) -> None:
    """Delete the prescription and its jobs; 409 while a job holds unarchived as-applied data."""
    rx = get_scoped(session, Prescription, rx_id, principal)
    refuse_if_evidence(session, "prescription", rx.id)
    delete_jobs(session, "prescription", rx.id)
    session.delete(rx)
    session.commit()
