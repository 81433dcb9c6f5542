"""Soil samples of a field in PostGIS: store an import (all or nothing), list, delete."""

from __future__ import annotations

import csv
import io
import json
import uuid
from typing import Any

from geoalchemy2.shape import to_shape
from shapely.geometry import Point
from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from fieldrx.agronomy.soil import SoilImport, read_soil_samples
from fieldrx.api.common import shape_to_db
from fieldrx.db.models import Field, SoilSample


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


def store_import(session: Session, field: Field, result: SoilImport, ndvi: dict[int, float]) -> str:
    """Add the samples of an accepted import (flush only; the caller commits)."""
    batch = uuid.uuid4().hex[:16]
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
            geom=shape_to_db(Point(s.lon, s.lat)),
            import_batch=batch,
        )
        for s in result.samples
    ]
    session.add_all(rows)
    session.flush()
    return batch


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
                },
            }
        )
    return {"type": "FeatureCollection", "features": feats, "total": len(feats)}


def delete_samples(session: Session, field_id: int) -> int:
    res = session.execute(delete(SoilSample).where(SoilSample.field_id == field_id))
    return int(res.rowcount or 0)
