"""The export-format registry and its one entry point (API ``/export?format=``, ``fieldrx rx``).

Every export format is one class below, registered with ``EXPORT_FORMATS``: its name,
label, media type, file name ending, the subjects it can export (``prescription``: a
prescription version's cells; ``job``: a job's as-applied data; ``package``: the tractor's
job package, built by its caller) and its writers. The API's accepted values
(``api.schemas.formats``), the OpenAPI document, the CLI's ``--format`` choices, the
services' dispatch and the UI's export menus (``GET /api/v1/export-formats``) are all
read from this registry: a new format is a new class here and nothing else.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from fieldrx.agronomy.cells import CellTable
from fieldrx.formats import FormatError
from fieldrx.registry import Registry

if TYPE_CHECKING:
    from fieldrx.formats.asapplied import AsAppliedPoints, AsAppliedTotals, CellRow
    from fieldrx.formats.zones import ZoneSummary

PRESCRIPTION = "prescription"
JOB = "job"
PACKAGE = "package"
SUBJECTS = (PRESCRIPTION, JOB, PACKAGE)


@dataclass(frozen=True)
class ExportOptions:
    """What a prescription file says beside the cells' rates, and how it is laid out.

    ``profile`` picks the Shapefile layout (``formats.shapefile.PROFILES``); zone exports
    (``isoxml-zones`` and the terminal profiles) take the rate class count
    ``zone_classes`` and the polygon limit ``max_polygons``. ``rate_unit`` and ``unit_lot``
    (the prescription's unit and the product lot values it converts through): the ISOXML
    task carries that unit's setpoints (DDI 0001 for l/ha) instead of mass ones; the other
    formats stay kg/ha. ``layer_name`` names the
    Shapefile's files inside the zip.
    """

    field_name: str = ""
    boundary_wgs84: Any = None
    product_name: str = "fertilizer"
    grid_cell_m: float | None = None
    properties: dict[str, Any] | None = None
    profile: str = "cells"
    zone_classes: int | None = None
    max_polygons: int | None = None
    rate_unit: str = "kg/ha"
    unit_lot: dict[str, float] | None = None
    layer_name: str = "prescription"


class AsAppliedSource(Protocol):
    """A job's as-applied data, read only when a format asks for it
    (``services.asapplied`` reads it from the database)."""

    def cells_csv(self) -> bytes: ...

    def cell_rows(self) -> list[CellRow]: ...

    def points(self) -> AsAppliedPoints: ...

    def taskdata(self) -> tuple[AsAppliedTotals, dict[str, Any]]:
        """The totals and the names ``formats.asapplied.write_asapplied_isoxml`` takes."""
        ...


@dataclass(frozen=True)
class Variant:
    """A further entry of a format in the UI's export menu: the format with these extra
    query parameters (a terminal's Shapefile layout)."""

    label: str
    params: dict[str, str]


class ExportFormat:
    """One export format; subclasses set the attributes and override the writers of the
    subjects they list."""

    name: str = ""
    label: str = ""
    media_type: str = "application/octet-stream"
    extension: str = ""  # a prescription file's name ending after the version's stem
    default_name: str = ""  # the file's name where there is no stem (``fieldrx rx``)
    job_extension: str = ""  # an as-applied file's name ending
    subjects: frozenset[str] = frozenset()
    variants: tuple[Variant, ...] = ()

    def write_prescription(
        self, cells: CellTable, opts: ExportOptions
    ) -> tuple[bytes, ZoneSummary | None]:
        raise FormatError(f"{self.name} does not export a prescription")

    def prescription_filename(self, stem: str, opts: ExportOptions) -> str:
        return f"{stem}{self.extension}"

    def write_job(self, source: AsAppliedSource, stem: str) -> bytes:
        raise FormatError(f"{self.name} does not export as-applied data")

    def job_filename(self, stem: str) -> str:
        return f"{stem}{self.job_extension}"


EXPORT_FORMATS: Registry[ExportFormat] = Registry("export format")


def _n_classes(opts: ExportOptions) -> int:
    from fieldrx.formats.zones import DEFAULT_ZONE_CLASSES

    return DEFAULT_ZONE_CLASSES if opts.zone_classes is None else int(opts.zone_classes)


def _setpoint(opts: ExportOptions) -> Any:
    from fieldrx.formats.isoxml import unit_setpoint

    return unit_setpoint(opts.rate_unit, opts.unit_lot)


@EXPORT_FORMATS.register
class GeoJsonExport(ExportFormat):
    name = "geojson"
    default_name = "prescription.geojson"
    label = "GeoJSON"
    media_type = "application/geo+json"
    extension = ".geojson"
    subjects = frozenset({PRESCRIPTION})

    def write_prescription(
        self, cells: CellTable, opts: ExportOptions
    ) -> tuple[bytes, ZoneSummary | None]:
        from fieldrx.formats.geojson import write_geojson

        return write_geojson(cells, opts.properties), None


@EXPORT_FORMATS.register
class CsvExport(ExportFormat):
    """Seed 001's Table 1 for a prescription; the report's per-cell table for a job."""

    name = "csv"
    default_name = "prescription.csv"
    label = "CSV"
    media_type = "text/csv"
    extension = ".csv"
    job_extension = ".csv"
    subjects = frozenset({PRESCRIPTION, JOB})

    def write_prescription(
        self, cells: CellTable, opts: ExportOptions
    ) -> tuple[bytes, ZoneSummary | None]:
        from fieldrx.formats.csv_table import write_table1_csv

        return write_table1_csv(cells), None

    def write_job(self, source: AsAppliedSource, stem: str) -> bytes:
        return source.cells_csv()


@EXPORT_FORMATS.register
class ShapefileExport(ExportFormat):
    """Zipped Shapefile: a prescription's cells (or a terminal's zones, by ``profile``);
    a job's cell polygons and record points."""

    name = "shapefile"
    default_name = "prescription_shp.zip"
    label = "Shapefile"
    media_type = "application/zip"
    extension = "_shp.zip"
    job_extension = ".zip"
    subjects = frozenset({PRESCRIPTION, JOB})
    # terminal layouts: rate zones within the terminal's polygon limit
    variants = (
        Variant("John Deere (Rx/)", {"profile": "deere"}),
        Variant("FieldView", {"profile": "fieldview"}),
        Variant("Raven / Ag Leader / Trimble", {"profile": "raven"}),
    )

    def write_prescription(
        self, cells: CellTable, opts: ExportOptions
    ) -> tuple[bytes, ZoneSummary | None]:
        from fieldrx.formats.shapefile import write_shapefile_zip, write_shapefile_zones_zip

        if opts.profile == "cells":
            return write_shapefile_zip(cells, opts.layer_name), None
        return write_shapefile_zones_zip(
            cells, opts.layer_name, opts.profile, _n_classes(opts), opts.max_polygons
        )

    def prescription_filename(self, stem: str, opts: ExportOptions) -> str:
        return (
            f"{stem}{self.extension}"
            if opts.profile == "cells"
            else (f"{stem}_{opts.profile}{self.extension}")
        )

    def write_job(self, source: AsAppliedSource, stem: str) -> bytes:
        from fieldrx.formats.asapplied import write_asapplied_shapefile_zip

        points = source.points()
        return write_asapplied_shapefile_zip(stem, source.cell_rows(), points)


@EXPORT_FORMATS.register
class IsoxmlExport(ExportFormat):
    """ISO 11783-10 TASKDATA.zip: a prescription as a grid; a job's TimeLog."""

    name = "isoxml"
    default_name = "TASKDATA.zip"
    label = "ISOXML"
    media_type = "application/zip"
    extension = "_TASKDATA_grid.zip"
    job_extension = "_TASKDATA.zip"
    subjects = frozenset({PRESCRIPTION, JOB})

    def write_prescription(
        self, cells: CellTable, opts: ExportOptions
    ) -> tuple[bytes, ZoneSummary | None]:
        from fieldrx.formats.isoxml import write_isoxml_grid

        data = write_isoxml_grid(
            cells,
            opts.field_name,
            opts.boundary_wgs84,
            opts.product_name,
            opts.grid_cell_m,
            _setpoint(opts),
        )
        return data, None

    def write_job(self, source: AsAppliedSource, stem: str) -> bytes:
        from fieldrx.formats.asapplied import write_asapplied_isoxml

        points = source.points()
        totals, names = source.taskdata()
        return write_asapplied_isoxml(points, totals, **names)


@EXPORT_FORMATS.register
class IsoxmlZonesExport(ExportFormat):
    """ISO 11783-10 TASKDATA.zip with the cells dissolved into rate zones."""

    name = "isoxml-zones"
    default_name = "TASKDATA.zip"
    label = "ISOXML zones"
    media_type = "application/zip"
    extension = "_TASKDATA_zones.zip"
    subjects = frozenset({PRESCRIPTION})

    def write_prescription(
        self, cells: CellTable, opts: ExportOptions
    ) -> tuple[bytes, ZoneSummary | None]:
        from fieldrx.formats.isoxml import write_isoxml_zones
        from fieldrx.formats.zones import DEFAULT_MAX_POLYGONS

        return write_isoxml_zones(
            cells,
            opts.field_name,
            opts.boundary_wgs84,
            opts.product_name,
            _n_classes(opts),
            DEFAULT_MAX_POLYGONS if opts.max_polygons is None else int(opts.max_polygons),
            setpoint=_setpoint(opts),
        )


@EXPORT_FORMATS.register
class JobPackageExport(ExportFormat):
    """The tractor's job package (``formats.jobpackage``); built by its caller, which
    knows the machine (``fieldrx rx``, ``services.jobpackage``)."""

    name = "job"
    default_name = "job.json"
    label = "Job package"
    media_type = "application/json"
    extension = ".json"
    subjects = frozenset({PACKAGE})


def export_formats(subject: str) -> tuple[str, ...]:
    """The names of the formats that export ``subject``, in registration order."""
    return EXPORT_FORMATS.names(lambda f: subject in f.subjects)


def export_format(name: str, subject: str) -> ExportFormat:
    """The format ``name`` if it exports ``subject``; ``FormatError`` otherwise."""
    fmt = EXPORT_FORMATS.get(name) if name in EXPORT_FORMATS else None
    if fmt is None or subject not in fmt.subjects:
        raise FormatError(
            f"unknown export format {name!r} (expected one of {list(export_formats(subject))})"
        )
    return fmt


def export_prescription(
    cells: CellTable,
    fmt: str,
    opts: ExportOptions = ExportOptions(),
    *,
    info: dict[str, Any] | None = None,
) -> tuple[bytes, str, str]:
    """Return (file bytes, media type, suggested file name) for one export format.

    ``cells`` carries the rates and flags (``CellTable.with_rates``). The job
    package is not a file export: see ``formats.jobpackage.build_job_package``.
    Zone exports put how they dissolved the cells into ``info["zones"]``
    (``ZoneSummary.to_dict``) when ``info`` is given.
    """
    f = export_format(fmt, PRESCRIPTION)
    data, summary = f.write_prescription(cells, opts)
    if summary is not None and info is not None:
        info["zones"] = summary.to_dict()
        info["note"] = summary.note()
    return data, f.media_type, f.default_name
