"""The export formats the server writes, from their registry: the UI builds its export
menus from this list instead of repeating it."""

from __future__ import annotations

from fastapi import APIRouter

from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.formats import ExportFormatOut, ExportFormatsOut, ExportVariantOut
from fieldrx.auth.deps import UserDep
from fieldrx.formats.export import EXPORT_FORMATS, SUBJECTS

router = APIRouter(tags=["formats"], responses=ERRORS)


@router.get("/export-formats", response_model=ExportFormatsOut)
def export_formats(principal: UserDep) -> ExportFormatsOut:
    """Every export format in menu order: name (the ``format=`` value), label, media type,
    the subjects it exports (``prescription``: ``/prescriptions/{id}/export``; ``job``:
    ``/jobs/{id}/export``; ``package``: the job package), file name endings and the extra
    menu entries (a terminal's Shapefile layout: ``profile=``)."""
    return ExportFormatsOut(
        items=[
            ExportFormatOut(
                name=f.name,
                label=f.label,
                media_type=f.media_type,
                subjects=[s for s in SUBJECTS if s in f.subjects],
                extension=f.extension,
                job_extension=f.job_extension,
                default_name=f.default_name,
                variants=[ExportVariantOut(label=v.label, params=v.params) for v in f.variants],
            )
            for f in EXPORT_FORMATS
        ]
    )
