"""Export formats as the API accepts and lists them, read from their registry.

The query parameters' types are ``Literal``s built from ``formats.export.EXPORT_FORMATS``
at import time, so FastAPI validates them and the OpenAPI document lists them as enums
exactly as hand-written ``Literal``s did; mypy sees ``str`` (a type built at run time is
beyond it).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

from pydantic import Field

from fieldrx.api.schemas.base import Out
from fieldrx.formats.export import JOB, PRESCRIPTION, export_formats

if TYPE_CHECKING:
    RxExportFormat = str
    JobExportFormat = str
else:
    RxExportFormat = Literal[export_formats(PRESCRIPTION)]
    JobExportFormat = Literal[export_formats(JOB)]


class ExportVariantOut(Out):
    """A further menu entry: the format with these query parameters."""

    label: str
    params: dict[str, str]


class ExportFormatOut(Out):
    """One export format of ``formats.export``'s registry."""

    name: str
    label: str
    media_type: str
    subjects: list[str]
    extension: str
    job_extension: str
    default_name: str
    variants: list[ExportVariantOut]


class ExportFormatsOut(Out):
    items: list[ExportFormatOut]


class LotValueOut(Out):
    key: str = Field(description="the product's field (and the prescription's lot key)")
    label: str
    unit: str
    min: float
    max: float


class RateUnitOut(Out):
    name: str = Field(description="the rate_unit value: kg/ha, l/ha, ...")
    label: str
    quantity: str = Field(description="mass | volume | count: what the unit meters")
    lot: list[LotValueOut] = Field(
        description="the product lot values the unit converts to kg/ha through"
    )
    seed_lot: bool = Field(
        description="the unit counts seeds: its product is a seed lot, never a fertiliser"
    )
    ddi_setpoint: int = Field(description="ISO 11783-11 setpoint DDI of the unit")
    ddi_actual: int = Field(description="ISO 11783-11 actual-value DDI of the unit")


class RateUnitsOut(Out):
    items: list[RateUnitOut]
