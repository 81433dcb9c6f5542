"""Export formats as the API accepts and lists them, read from their registry.

The query parameters' types are ``Literal``s built from ``formats.export.EXPORT_FORMATS``
at import time, so FastAPI validates them and the OpenAPI document lists them as enums
exactly as hand-written ``Literal``s did; mypy sees ``str`` (a type built at run time is
beyond it).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

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
