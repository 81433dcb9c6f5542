"""Prescription cells as an RFC 7946 GeoJSON FeatureCollection (lon/lat, path order)."""

from __future__ import annotations

from typing import Any

import numpy as np

from fieldrx.agronomy.cells import CellTable, flag_strings
from fieldrx.formats import FormatError
from fieldrx.geo.cells import GEOJSON_DECIMALS, Column

COORD_DECIMALS = GEOJSON_DECIMALS


def write_geojson(cells: CellTable, properties: dict[str, Any] | None = None) -> bytes:
    """Compact UTF-8 GeoJSON bytes (see ``prescription_geojson``), written by the cell
    type's one GeoJSON writer (``Cells.geojson_bytes``)."""
    if not np.isfinite(cells.rate_kg_ha).all():
        raise FormatError("GeoJSON export: a rate is not finite")
    n = len(cells)
    columns: dict[str, Column] = {
        "seq": cells.seq,
        "swath": cells.swath,
        "rate_kg_ha": np.round(cells.rate_kg_ha, 3).astype(float),
        "unit": ["kg/ha"] * n,
        "flag": flag_strings(cells.flags),
        "area_m2": np.round(cells.area_m2, 3).astype(float),
    }
    return cells.geojson_bytes(columns, properties, COORD_DECIMALS)
