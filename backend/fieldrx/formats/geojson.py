"""Prescription cells as an RFC 7946 GeoJSON FeatureCollection (lon/lat, path order)."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import shapely

from fieldrx.agronomy.cells import CellTable, flag_strings

COORD_DECIMALS = 9  # ~0.1 mm; RFC 7946 recommends no more than needed


def prescription_geojson(
    cells: CellTable, properties: dict[str, Any] | None = None
) -> dict[str, Any]:
    """FeatureCollection of the clipped cells with seq, swath, rate_kg_ha, unit, flag, area.

    ``properties`` (e.g. prescription id, version, model) go on the collection
    as a foreign member ``properties`` that GeoJSON readers ignore.
    """
    polys = shapely.set_precision(cells.polygons_wgs84(), 10.0**-COORD_DECIMALS)
    geoms = shapely.to_geojson(polys)
    flags = flag_strings(cells.flags)
    rates = np.round(cells.rate_kg_ha, 3)
    feats = []
    for i in range(len(cells)):
        feats.append(
            {
                "type": "Feature",
                "id": int(cells.seq[i]),
                "geometry": json.loads(geoms[i]),
                "properties": {
                    "seq": int(cells.seq[i]),
                    "swath": int(cells.swath[i]),
                    "rate_kg_ha": float(rates[i]),
                    "unit": "kg/ha",
                    "flag": flags[i],
                    "area_m2": round(float(cells.area_m2[i]), 3),
                },
            }
        )
    out: dict[str, Any] = {"type": "FeatureCollection", "features": feats}
    if properties:
        out["properties"] = properties
    return out


def write_geojson(cells: CellTable, properties: dict[str, Any] | None = None) -> bytes:
    """Compact UTF-8 GeoJSON bytes."""
    return json.dumps(
        prescription_geojson(cells, properties), separators=(",", ":"), allow_nan=False
    ).encode()
