"""One entry point for prescription file exports (API ``/export?format=`` and ``fieldrx rx``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fieldrx.agronomy.cells import CellTable
from fieldrx.formats import MEDIA_TYPES, FormatError

FILE_FORMATS = ("geojson", "csv", "shapefile", "isoxml", "isoxml-zones")


@dataclass(frozen=True)
class ExportOptions:
    """What a prescription file says beside the cells' rates, and how it is laid out.

    ``profile`` picks the Shapefile layout (``formats.shapefile.PROFILES``); zone exports
    (``isoxml-zones`` and the terminal profiles) take the rate class count
    ``zone_classes`` and the polygon limit ``max_polygons``. ``volume_density_kg_l`` (an
    l/ha prescription's product density): the ISOXML task carries volume setpoints (DDI
    0001) instead of mass ones; the other formats stay kg/ha. ``layer_name`` names the
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
    volume_density_kg_l: float | None = None
    layer_name: str = "prescription"


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
    from fieldrx.formats.zones import DEFAULT_MAX_POLYGONS, DEFAULT_ZONE_CLASSES

    n_classes = DEFAULT_ZONE_CLASSES if opts.zone_classes is None else int(opts.zone_classes)
    summary = None
    if fmt == "geojson":
        from fieldrx.formats.geojson import write_geojson

        data = write_geojson(cells, opts.properties)
    elif fmt == "csv":
        from fieldrx.formats.csv_table import write_table1_csv

        data = write_table1_csv(cells)
    elif fmt == "shapefile":
        from fieldrx.formats.shapefile import write_shapefile_zip, write_shapefile_zones_zip

        if opts.profile == "cells":
            data = write_shapefile_zip(cells, opts.layer_name)
        else:
            data, summary = write_shapefile_zones_zip(
                cells, opts.layer_name, opts.profile, n_classes, opts.max_polygons
            )
    elif fmt == "isoxml":
        from fieldrx.formats.isoxml import write_isoxml_grid

        data = write_isoxml_grid(
            cells,
            opts.field_name,
            opts.boundary_wgs84,
            opts.product_name,
            opts.grid_cell_m,
            _setpoint(opts.volume_density_kg_l),
        )
    elif fmt == "isoxml-zones":
        from fieldrx.formats.isoxml import write_isoxml_zones

        data, summary = write_isoxml_zones(
            cells,
            opts.field_name,
            opts.boundary_wgs84,
            opts.product_name,
            n_classes,
            DEFAULT_MAX_POLYGONS if opts.max_polygons is None else int(opts.max_polygons),
            setpoint=_setpoint(opts.volume_density_kg_l),
        )
    else:
        raise FormatError(f"unknown export format {fmt!r} (expected one of {list(FILE_FORMATS)})")
    if summary is not None and info is not None:
        info["zones"] = summary.to_dict()
        info["note"] = summary.note()
    media, filename = MEDIA_TYPES[fmt]
    return data, media, filename


def _setpoint(volume_density_kg_l: float | None) -> Any:
    from fieldrx.formats.isoxml import MASS, volume_setpoint

    return MASS if volume_density_kg_l is None else volume_setpoint(volume_density_kg_l)
