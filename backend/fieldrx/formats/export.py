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
) -> tuple[bytes, str, str]:
    """Return (file bytes, media type, suggested file name) for one export format.

    ``cells`` carries the rates and flags (``CellTable.with_rates``). The job
    package is not a file export: see ``formats.jobpackage.build_job_package``.
    """
    if fmt == "geojson":
        from fieldrx.formats.geojson import write_geojson

        data = write_geojson(cells, properties)
    elif fmt == "csv":
        from fieldrx.formats.csv_table import write_table1_csv

        data = write_table1_csv(cells)
    elif fmt == "shapefile":
        from fieldrx.formats.shapefile import write_shapefile_zip

        data = write_shapefile_zip(cells, "prescription")
    elif fmt == "isoxml":
        from fieldrx.formats.isoxml import write_isoxml_grid

        data = write_isoxml_grid(cells, field_name, boundary_wgs84, product_name, grid_cell_m)
    elif fmt == "isoxml-zones":
        from fieldrx.formats.isoxml import write_isoxml_zones

        data = write_isoxml_zones(cells, field_name, boundary_wgs84, product_name)
    else:
        raise FormatError(f"unknown export format {fmt!r} (expected one of {list(FILE_FORMATS)})")
    media, filename = MEDIA_TYPES[fmt]
    return data, media, filename
