"""Imagery rows: what an ingested COG is recorded as (the inline upload and the background
task record it the same way)."""

from __future__ import annotations

import datetime as dt

from geoalchemy2.shape import from_shape
from shapely import wkb

from fieldrx.db.models import Imagery
from fieldrx.imagery.ingest import IngestResult


def imagery_row(
    *,
    organisation_id: int,
    field_id: int,
    kind: str,
    name: str,
    filename: str,
    storage_key: str,
    res: IngestResult,
    created_by: int | None,
) -> Imagery:
    """The ``imagery`` row of a converted raster (not added to a session)."""
    return Imagery(
        organisation_id=organisation_id,
        field_id=field_id,
        kind=kind,
        name=name or filename or kind,
        filename=filename[:255],
        storage_key=storage_key,
        acquired_on=dt.date.fromisoformat(res.acquired_on) if res.acquired_on else None,
        source_crs=res.source_crs,
        resolution_m=res.resolution_m,
        width=res.width,
        height=res.height,
        band_count=res.band_count,
        dtype=res.dtype,
        bands=res.bands,
        nodata=res.nodata,
        size_bytes=res.size_bytes,
        footprint=from_shape(wkb.loads(res.footprint_wkb), srid=4326),
        created_by=created_by,
    )
