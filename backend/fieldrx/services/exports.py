"""Prescription version -> file bytes through fieldrx.formats (GeoJSON, CSV, Shapefile, ISOXML)."""

from __future__ import annotations

import re
from typing import Any

from geoalchemy2.shape import to_shape
from sqlalchemy.orm import Session

from fieldrx.db.models import Field, Plan, Prescription, PrescriptionVersion
from fieldrx.services.prescriptions.params import RxError, rx_unit_lot
from fieldrx.services.prescriptions.versions import version_cells


def _slug(text: str, limit: int) -> str:
    """ASCII letters, digits, ``-`` and ``_`` only (what every terminal's file system takes),
    cut at ``limit`` characters on a word boundary where there is one."""
    s = re.sub(r"[^A-Za-z0-9-]+", "_", text).strip("_")
    if len(s) > limit:
        cut = s[:limit]
        s = cut.rsplit("_", 1)[0] if "_" in cut[limit // 2 :] else cut
    return s.strip("_")


def file_stem(field_name: str, rx: Prescription, ver: PrescriptionVersion) -> str:
    """The name of a version's files: field, product, the version's date, then the
    prescription and version (``Home_field_Urea_46N_20261128_rx2v3``). Readable on a
    terminal's file list and unique per version, so two prescriptions in one ``Rx/`` folder
    of a display card never overwrite each other."""
    date = ver.created_at.strftime("%Y%m%d") if ver.created_at is not None else ""
    parts = (
        _slug(field_name, 24) or "field",
        _slug(rx.product or "fertilizer", 20),
        date,
        f"rx{rx.id}v{ver.version}",
    )
    return "_".join(p for p in parts if p)


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
    from fieldrx.formats import FormatError
    from fieldrx.formats.export import (
        PRESCRIPTION,
        ExportOptions,
        export_format,
        export_prescription,
    )

    try:
        kind = export_format(fmt, PRESCRIPTION)
    except FormatError as exc:
        raise RxError(str(exc)) from exc
    cells = version_cells(session, rx, ver)
    plan = session.get(Plan, rx.plan_id)
    field = session.get(Field, plan.field_id) if plan is not None else None
    boundary = None if field is None else to_shape(field.boundary)
    props = {"prescription_id": rx.id, "version": ver.version, "model": rx.model}
    unit, lot = rx_unit_lot(rx)
    stem = file_stem("" if field is None else field.name, rx, ver)
    opts = ExportOptions(
        field_name="" if field is None else field.name,
        boundary_wgs84=boundary,
        product_name=rx.product or "fertilizer",
        properties=props,
        profile=profile,
        zone_classes=zone_classes,
        max_polygons=max_polygons,
        rate_unit=unit.name,
        unit_lot=lot,
        layer_name=stem,
    )
    data, media, _ = export_prescription(cells, fmt, opts, info=info)
    return data, media, kind.prescription_filename(stem, opts)
