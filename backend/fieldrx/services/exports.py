"""Prescription version -> file bytes through fieldrx.formats (GeoJSON, CSV, Shapefile, ISOXML)."""

from __future__ import annotations

import re

from geoalchemy2.shape import to_shape
from sqlalchemy.orm import Session

from fieldrx.db.models import Field, Plan, Prescription, PrescriptionVersion
from fieldrx.formats import MEDIA_TYPES
from fieldrx.services.prescriptions import RxError, version_cells

FORMATS = ("geojson", "csv", "shapefile", "isoxml", "isoxml-zones")


def _stem(rx: Prescription, ver: PrescriptionVersion) -> str:
    name = re.sub(r"[^A-Za-z0-9_-]+", "_", rx.name or "prescription").strip("_")[:40]
    return f"{name or 'prescription'}_rx{rx.id}_v{ver.version}"


def export_version(
    session: Session, rx: Prescription, ver: PrescriptionVersion, fmt: str
) -> tuple[bytes, str, str]:
    """(bytes, media type, download file name) of one version in one format."""
    if fmt not in FORMATS:
        raise RxError(f"unknown export format {fmt!r} (expected one of {list(FORMATS)})")
    cells = version_cells(session, rx, ver)
    plan = session.get(Plan, rx.plan_id)
    field = session.get(Field, plan.field_id) if plan is not None else None
    boundary = None if field is None else to_shape(field.boundary)
    field_name = "" if field is None else field.name
    product = rx.product or "fertilizer"
    media, default_name = MEDIA_TYPES[fmt]
    stem = _stem(rx, ver)
    if fmt == "geojson":
        from fieldrx.formats.geojson import write_geojson

        props = {"prescription_id": rx.id, "version": ver.version, "model": rx.model}
        return write_geojson(cells, props), media, f"{stem}.geojson"
    if fmt == "csv":
        from fieldrx.formats.csv_table import write_table1_csv

        return write_table1_csv(cells), media, f"{stem}.csv"
    if fmt == "shapefile":
        from fieldrx.formats.shapefile import write_shapefile_zip

        return write_shapefile_zip(cells, name=stem[:64]), media, f"{stem}_shp.zip"
    from fieldrx.formats import isoxml

    if fmt == "isoxml":
        data = isoxml.write_isoxml_grid(cells, field_name, boundary, product)
    else:
        data = isoxml.write_isoxml_zones(cells, field_name, boundary, product)
    suffix = "grid" if fmt == "isoxml" else "zones"
    return data, media, f"{stem}_TASKDATA_{suffix}.zip"
