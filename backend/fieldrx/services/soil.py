"""Soil samples of a field in PostGIS: store an import (all or nothing), list, delete.

Every upload is a ``SoilImport`` row (file name, sha256 of its bytes, counts);
its samples point at it and are deleted with it. The same bytes uploaded to the
same field again are refused (``DuplicateImport``), and samples farther than
the parser's tolerance outside the field are stored only when asked to.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import uuid
from typing import Any, cast

from geoalchemy2.shape import from_shape, to_shape
from shapely.geometry import Point
from sqlalchemy import CursorResult, Delete, delete, func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from fieldrx.agronomy.soil import OUTSIDE_TOLERANCE_M, SoilImport, read_soil_samples
from fieldrx.agronomy.soil_lab import (
    DEFAULT_UNIT,
    HEADER,
    TARGETS,
    UNITS,
    Mapping,
    Table,
    apply_mapping,
    example_lab_csv,
    read_table,
    suggest_mapping,
)
from fieldrx.db.models import Field, SoilSample
from fieldrx.db.models import SoilImport as SoilImportRow
from fieldrx.geo.crs import crs_name, import_crs_choices


class ImportRefused(ValueError):
    """An import that stores nothing: ``status`` and ``extra`` go into the answer."""

    def __init__(self, status: int, message: str, **extra: Any) -> None:
        super().__init__(message)
        self.status = status
        self.extra = extra



def _deleted(session: Session, stmt: Delete) -> int:
    """Rows a DELETE removed (a DML statement's result is a CursorResult, with rowcount)."""
    res = cast(CursorResult[Any], session.execute(stmt))
    return int(res.rowcount or 0)

def file_digest(data: bytes) -> str:
    return "sha256:" + hashlib.sha256(data).hexdigest()


def ndvi_by_row(filename: str, data: bytes) -> dict[int, float]:
    """Optional ``ndvi`` column/property by the parser's row numbering (CSV header = row 1,
    GeoJSON feature index). agronomy.soil does not read NDVI; the NDVI model needs it."""
    out: dict[int, float] = {}
    try:
        if filename.lower().endswith((".geojson", ".json")):
            feats = json.loads(data).get("features") or []
            for i, f in enumerate(feats):
                props = {str(k).lower(): v for k, v in ((f or {}).get("properties") or {}).items()}
                if props.get("ndvi") is not None:
                    out[i] = float(props["ndvi"])
        else:
            text = data.decode("utf-8-sig")
            first = text.splitlines()[0] if text else ""
            delim = max([",", ";", "\t"], key=first.count)
            reader = csv.reader(io.StringIO(text), delimiter=delim)
            header = [h.strip().lower() for h in next(reader)]
            if "ndvi" not in header:
                return out
            j = header.index("ndvi")
            for i, row in enumerate(reader, start=2):
                if j < len(row) and row[j].strip():
                    out[i] = float(row[j])
    except (ValueError, TypeError, AttributeError, UnicodeDecodeError, StopIteration):
        return out
    return out


def parse_for_field(
    field: Field, filename: str, data: bytes, epsg: int | None, skip_bad_rows: bool
) -> SoilImport:
    """Run the pure parser with the field boundary (raises SoilFormatError)."""
    return read_soil_samples(
        filename,
        data,
        epsg=epsg,
        skip_bad_rows=skip_bad_rows,
        boundary_wgs84=to_shape(field.boundary),
    )


def store_import(
    session: Session,
    field: Field,
    filename: str,
    data: bytes,
    result: SoilImport,
    include_outside: bool,
    user_id: int | None,
    replace: bool = False,
) -> dict[str, Any]:
    """Store an accepted import (flush only; the caller commits) and describe it.

    Samples outside the field (beyond ``OUTSIDE_TOLERANCE_M``) are stored only
    with ``include_outside``; when none is left the import is refused (422) so
    that nothing is stored. The same bytes twice on one field: 409. ``replace``
    deletes the field's samples and imports first, in the same transaction (a
    refusal after it rolls the deletion back with everything else).
    """
    replaced = delete_samples(session, field.id) if replace else 0
    digest = file_digest(data)
    same = session.scalar(
        select(SoilImportRow).where(
            SoilImportRow.field_id == field.id, SoilImportRow.sha256 == digest
        )
    )
    report = result.summary()
    if same is not None:
        raise ImportRefused(
            409,
            f"this file was already imported into field {field.id} as import {same.id} "
            f"({same.filename or 'no name'}, {same.n_samples} samples, "
            f"{same.created_at:%Y-%m-%d %H:%M} UTC); nothing stored: delete that import to "
            "import the file again",
            duplicate_of=import_out(same),
            imported=0,
        )
    keep = result.samples if include_outside else result.inside_samples()
    if not keep:
        far = min(result.outside_distance_m or [0.0])
        raise ImportRefused(
            422,
            f"none of the {len(result.samples)} samples lies in field {field.id} (the nearest is "
            f"{far:,.0f} m outside, tolerance {OUTSIDE_TOLERANCE_M:g} m); nothing stored: is "
            "this the right field? (include_outside=true stores them anyway)",
            where=filename,
            outside=report["outside"],
            imported=0,
        )
    batch = uuid.uuid4().hex[:16]
    imp = SoilImportRow(
        organisation_id=field.organisation_id,
        field_id=field.id,
        filename=filename[:255],
        sha256=digest,
        batch=batch,
        n_samples=len(keep),
        n_outside=len(result.outside),
        outside_stored=include_outside and bool(result.outside),
        created_by=user_id,
    )
    session.add(imp)
    try:
        session.flush()
    except IntegrityError as exc:  # the same file, uploaded at the same moment
        raise ImportRefused(
            409,
            f"this file is being imported into field {field.id} by another request; nothing stored",
            imported=0,
        ) from exc
    ndvi = ndvi_by_row(filename, data)
    rows = [
        SoilSample(
            organisation_id=field.organisation_id,
            field_id=field.id,
            sample_id=s.sample_id[:100],
            depth_cm=s.depth_cm,
            n_mg_kg=s.n_mg_kg,
            p_mg_kg=s.p_mg_kg,
            k_mg_kg=s.k_mg_kg,
            om_pct=None if s.om_g_kg is None else s.om_g_kg / 10.0,  # g/kg -> %
            ph=s.ph,
            ndvi=ndvi.get(s.row),
            n_form=s.n_form,
            geom=from_shape(Point(s.lon, s.lat), srid=4326),
            import_batch=batch,
            import_id=imp.id,
        )
        for s in keep
    ]
    session.add_all(rows)
    session.flush()
    session.refresh(imp)
    n_out = len(result.outside)
    return {
        "imported": len(keep),
        "import_batch": batch,
        "import": import_out(imp),
        "skipped": len(result.errors),
        "errors": report["errors"],
        "outside": report["outside"],
        "n_outside": n_out,
        "outside_stored": imp.outside_stored,
        "outside_tolerance_m": OUTSIDE_TOLERANCE_M,
        "replaced": replaced,
        "message": f"{len(keep)} samples imported"
        + (f", {replaced} earlier samples replaced" if replace else "")
        + (
            ""
            if not n_out
            else f"; {n_out} outside the field (> {OUTSIDE_TOLERANCE_M:g} m) "
            + ("stored as asked" if imp.outside_stored else "not stored")
        ),
    }


def import_out(imp: SoilImportRow) -> dict[str, Any]:
    return {
        "id": imp.id,
        "field_id": imp.field_id,
        "filename": imp.filename,
        "sha256": imp.sha256,
        "batch": imp.batch,
        "n_samples": imp.n_samples,
        "n_outside": imp.n_outside,
        "outside_stored": imp.outside_stored,
        "created_by": imp.created_by,
        "created_at": imp.created_at.isoformat() if imp.created_at else None,
    }


def list_imports(session: Session, field_id: int) -> dict[str, Any]:
    """A field's imports, newest first, with the number of samples each still has."""
    counts = dict(
        session.execute(
            select(SoilSample.import_id, func.count())
            .where(SoilSample.field_id == field_id)
            .group_by(SoilSample.import_id)
        ).all()
    )
    rows = session.scalars(
        select(SoilImportRow)
        .where(SoilImportRow.field_id == field_id)
        .order_by(SoilImportRow.id.desc())
    ).all()
    items = [{**import_out(r), "n_stored": int(counts.get(r.id, 0))} for r in rows]
    return {"items": items, "total": len(items)}


def delete_import(session: Session, field_id: int, import_id: int) -> int | None:
    """Delete one import and its samples; None when the field has no such import."""
    imp = session.get(SoilImportRow, import_id)
    if imp is None or imp.field_id != field_id:
        return None
    n = _deleted(session, delete(SoilSample).where(SoilSample.import_id == imp.id))
    session.delete(imp)
    session.flush()
    return int(n or 0)


def delete_sample(session: Session, field_id: int, sample_pk: int) -> bool:
    """Delete one sample (by its row id); its import's count follows in ``list_imports``."""
    return bool(
        _deleted(
            session,
            delete(SoilSample).where(SoilSample.field_id == field_id, SoilSample.id == sample_pk),
        )
    )


def sample_rows(session: Session, field_id: int) -> list[SoilSample]:
    return list(
        session.scalars(
            select(SoilSample).where(SoilSample.field_id == field_id).order_by(SoilSample.id)
        )
    )


def samples_geojson(rows: list[SoilSample]) -> dict[str, Any]:
    feats = []
    for r in rows:
        p = to_shape(r.geom)
        feats.append(
            {
                "type": "Feature",
                "id": r.id,
                "geometry": {"type": "Point", "coordinates": [p.x, p.y]},
                "properties": {
                    "id": r.id,
                    "sample_id": r.sample_id,
                    "depth_cm": r.depth_cm,
                    "n_mg_kg": r.n_mg_kg,
                    "p_mg_kg": r.p_mg_kg,
                    "k_mg_kg": r.k_mg_kg,
                    "om_pct": r.om_pct,
                    "ph": r.ph,
                    "ndvi": r.ndvi,
                    "import_batch": r.import_batch,
                    "import_id": r.import_id,
                },
            }
        )
    return {"type": "FeatureCollection", "features": feats, "total": len(feats)}


def delete_samples(session: Session, field_id: int) -> int:
    """Every sample and import of the field."""
    n = _deleted(session, delete(SoilSample).where(SoilSample.field_id == field_id))
    session.execute(delete(SoilImportRow).where(SoilImportRow.field_id == field_id))
    return n


PREVIEW_ROWS = 20  # converted rows shown in a preview


def mapping_out(m: Mapping) -> dict[str, Any]:
    return {
        "columns": dict(m.columns),
        "units": {t: m.unit(t) for t in m.columns if len(UNITS.get(t, {})) > 1},
        "epsg": m.epsg,
        "bulk_density_g_cm3": m.bulk_density_g_cm3,
        "n_form": m.n_form,
    }


def _sample_row(s: Any) -> dict[str, Any]:
    return {
        "row": s.row,
        "sample_id": s.sample_id,
        "lon": round(s.lon, 7),
        "lat": round(s.lat, 7),
        "depth_cm": s.depth_cm,
        "n_mg_kg": s.n_mg_kg,
        "p_mg_kg": s.p_mg_kg,
        "k_mg_kg": s.k_mg_kg,
        "om_g_kg": s.om_g_kg,
        "ph": s.ph,
    }


def lab_result(
    field: Field, filename: str, data: bytes, mapping: Mapping | None
) -> tuple[Table, Mapping, Mapping, SoilImport]:
    """Read a lab file and apply ``mapping`` (None: the suggested one) with the field's
    boundary; returns the table, the suggestion, the mapping used and the result. Pure
    apart from reading ``field``; raises ``SoilFormatError`` for an unreadable file."""
    boundary = to_shape(field.boundary)
    c = boundary.representative_point()
    table = read_table(filename, data)
    suggested = suggest_mapping(table, (c.x, c.y))
    used = mapping or suggested
    return table, suggested, used, apply_mapping(table, used, boundary)


def count_samples(session: Session, field_id: int) -> int:
    n = session.scalar(
        select(func.count()).select_from(SoilSample).where(SoilSample.field_id == field_id)
    )
    return int(n or 0)


def lab_preview(
    field: Field, filename: str, data: bytes, mapping: Mapping | None, n_existing: int
) -> dict[str, Any]:
    """What confirming this file with this mapping would store (no database access: runs in
    a bounded child process); ``n_existing`` is the field's sample count now."""
    table, suggested, used, res = lab_result(field, filename, data, mapping)
    c = to_shape(field.boundary).representative_point()
    summary = res.summary()
    mapped = {col: t for t, col in used.columns.items()}
    inside = res.inside_samples()
    mapping_errors = res.rejected and any(e.kind == HEADER for e in res.errors)
    return {
        "filename": filename,
        "delimiter": table.delimiter,
        "encoding": table.encoding,
        "decimal_comma": table.decimal_comma,
        "columns": [
            {"name": h, "examples": table.column(h)[:3], "target": mapped.get(h)}
            for h in table.header
        ],
        "targets": [
            {
                "target": t,
                "label": label,
                "stored_unit": unit,
                "units": list(UNITS[t]) if len(UNITS[t]) > 1 else [],
                "default_unit": DEFAULT_UNIT[t] if len(UNITS[t]) > 1 else "",
            }
            for t, (_, unit, label) in TARGETS.items()
        ],
        "crs_options": [{"epsg": e, "name": crs_name(e)} for e in import_crs_choices(c.x, c.y)],
        "suggested": mapping_out(suggested),
        "mapping": mapping_out(used),
        "mapping_ok": not mapping_errors,
        "n_rows": len(table.rows),
        "n_accepted": len(res.samples),
        "n_inside": len(inside),
        "n_rejected": len({e.row for e in res.errors if e.kind != HEADER}),
        "rejected": summary["errors"],
        "n_outside": len(res.outside),
        "outside": summary["outside"],
        "outside_tolerance_m": OUTSIDE_TOLERANCE_M,
        "rows": [_sample_row(s) for s in res.samples[:PREVIEW_ROWS]],
        "n_existing": n_existing,
    }


def example_file(field: Field) -> tuple[str, int]:
    """An example lab file with points inside ``field`` (text, EPSG of its coordinates)."""
    return example_lab_csv(to_shape(field.boundary))
