"""One entry point for prescription file exports (API ``/export?format=`` and ``fieldrx rx``)."""

from __future__ import annotations

from typing import Any

from fieldrx.agronomy.cells import CellTable
from fieldrx.formats import MEDIA_TYPES, FormatError

FILE_FORMATS = ("geojson", "csv", "shapefile", "isoxml", "isoxml-zones")


def export_prescription(
    cells: CellTable,
    fmt: str,
    *,
    field_name: str = "",
    boundary_wgs84: Any = None,
    product_name: str = "fertilizer",
    grid_cell_m: float | None = None,
    properties: dict[str, Any] | None = None,
    profile: str = "cells",
    zone_classes: int | None = None,
    max_polygons: int | None = None,
    info: dict[str, Any] | None = None,
    volume_density_kg_l: float | None = None,
    layer_name: str = "prescription",
) -> tuple[bytes, str, str]:
    """Return (file bytes, media type, suggested file name) for one export format.

    ``cells`` carries the rates and flags (``CellTable.with_rates``). The job
    package is not a file export: see ``formats.jobpackage.build_job_package``.
    ``profile`` picks the Shapefile layout (``formats.shapefile.PROFILES``);
    zone exports (``isoxml-zones`` and the terminal profiles) take the rate
    class count and polygon limit, and put how they dissolved the cells into
    ``info["zones"]`` (``ZoneSummary.to_dict``) when ``info`` is given.
    ``volume_density_kg_l`` (an l/ha prescription's product density): the ISOXML task
    carries volume setpoints (DDI 0001) instead of mass ones; the other formats stay kg/ha.
    ``layer_name`` names the Shapefile's files inside the zip.
    """
    from fieldrx.formats.zones import DEFAULT_MAX_POLYGONS, DEFAULT_ZONE_CLASSES

    n_classes = DEFAULT_ZONE_CLASSES if zone_classes is None else int(zone_classes)
    summary = None
    if fmt == "geojson":
        from fieldrx.formats.geojson import write_geojson

        data = write_geojson(cells, properties)
    elif fmt == "csv":
        from fieldrx.formats.csv_table import write_table1_csv

        data = write_table1_csv(cells)
    elif fmt == "shapefile":
        from fieldrx.formats.shapefile import write_shapefile_zip, write_shapefile_zones_zip

        if profile == "cells":
            data = write_shapefile_zip(cells, layer_name)
        else:
            data, summary = write_shapefile_zones_zip(
                cells, layer_name, profile, n_classes, max_polygons
            )
    elif fmt == "isoxml":
        from fieldrx.formats.isoxml import write_isoxml_grid

        data = write_isoxml_grid(
            cells,
            field_name,
            boundary_wgs84,
            product_name,
            grid_cell_m,
            _setpoint(volume_density_kg_l),
        )
    elif fmt == "isoxml-zones":
        from fieldrx.formats.isoxml import write_isoxml_zones

        data, summary = write_isoxml_zones(
            cells,
            field_name,
            boundary_wgs84,
            product_name,
            n_classes,
            DEFAULT_MAX_POLYGONS if max_polygons is None else int(max_polygons),
            setpoint=_setpoint(volume_density_kg_l),
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
