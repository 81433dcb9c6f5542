"""The export formats the server writes and the rate units it prescribes in, from their
registries: the UI builds its export menus and unit choices from these lists instead of
repeating them."""

from __future__ import annotations

from fastapi import APIRouter
from fieldrx_edge.rateunits.registry import units

from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.formats import (
    ExportFormatOut,
    ExportFormatsOut,
    ExportVariantOut,
    RateUnitOut,
    RateUnitsOut,
)
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


@router.get("/rate-units", response_model=RateUnitsOut)
def rate_units(principal: UserDep) -> RateUnitsOut:
    """Every rate unit a prescription may be given in (``rate_unit``), kg/ha first, with the
    product lot values it converts through (``lot`` of a prescription request) and its
    ISO 11783 setpoint and actual DDIs."""
    return RateUnitsOut(items=[RateUnitOut.model_validate(u.describe()) for u in units()])
