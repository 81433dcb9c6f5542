"""Prescription version -> file bytes through fieldrx.formats (GeoJSON, CSV, Shapefile, ISOXML)."""

from __future__ import annotations

import re
from typing import Any

from geoalchemy2.shape import to_shape
from sqlalchemy.orm import Session

from fieldrx.db.models import Field, Plan, Prescription, PrescriptionVersion
from fieldrx.services.prescriptions import RxError, rx_rate_unit, version_cells

FORMATS = ("geojson", "csv", "shapefile", "isoxml", "isoxml-zones")


def _stem(rx: Prescription, ver: PrescriptionVersion) -> str:
    name = re.sub(r"[^A-Za-z0-9_-]+", "_", rx.name or "prescription").strip("_")[:40]
    return f"{name or 'prescription'}_rx{rx.id}_v{ver.version}"


def export_version(
    session: Session,
    rx: Prescription,
    ver: PrescriptionVersion,
    fmt: str,
    *,
    profile: str = "cells",
    zone_classes: int | None = None,
    max_polygons: int | None = None,
    info: dict[str, Any] | None = None,
) -> tuple[bytes, str, str]:
    """(bytes, media type, download file name) of one version in one format.

    The writing itself is ``formats.export.export_prescription`` (one home);
    this adds the field, product and a file name. Zone exports report how the
    cells were dissolved in ``info`` (the API sends it as a header).
    """
    from fieldrx.formats.export import export_prescription

    if fmt not in FORMATS:
        raise RxError(f"unknown export format {fmt!r} (expected one of {list(FORMATS)})")
    cells = version_cells(session, rx, ver)
    plan = session.get(Plan, rx.plan_id)
    field = session.get(Field, plan.field_id) if plan is not None else None
    boundary = None if field is None else to_shape(field.boundary)
    props = {"prescription_id": rx.id, "version": ver.version, "model": rx.model}
    unit, density = rx_rate_unit(rx)
    data, media, _ = export_prescription(
        cells,
        fmt,
        field_name="" if field is None else field.name,
        boundary_wgs84=boundary,
        product_name=rx.product or "fertilizer",
        properties=props,
        profile=profile,
        zone_classes=zone_classes,
        max_polygons=max_polygons,
        info=info,
        volume_density_kg_l=density if unit == "l/ha" else None,
    )
    stem = _stem(rx, ver)
    if fmt == "isoxml" or fmt == "isoxml-zones":
        suffix = "grid" if fmt == "isoxml" else "zones"
        return data, media, f"{stem}_TASKDATA_{suffix}.zip"
    ext = {"geojson": ".geojson", "csv": ".csv"}.get(fmt)
    if ext is not None:
        return data, media, f"{stem}{ext}"
    tail = "_shp.zip" if profile == "cells" else f"_{profile}_shp.zip"
    return data, media, f"{stem}{tail}"
