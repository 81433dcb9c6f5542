"""Zipped Shapefile for farm software (Climate FieldView, Raven, Ag Leader, JD Ops Center).

A flat zip (no folder) of ``<name>.shp/.shx/.dbf/.prj/.cpg``: WGS84 polygons
(exterior rings clockwise as the Shapefile spec wants), a numeric ``RATE``
column and its unit in ``UNIT`` ("kg/ha"), plus ``SEQ``, ``SWATH``, ``FLAG``
and ``AREA_M2``. Written with pyshp.
"""

from __future__ import annotations

import io
import zipfile

import numpy as np
import shapefile as pyshp
import shapely

from fieldrx.agronomy.cells import CellTable, flag_strings, round_coords
from fieldrx.formats import FormatError

WGS84_PRJ = (
    'GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,298.257223563]],'
    'PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]]'
)


def _rings_per_cell(polys: np.ndarray) -> list[list[list[list[float]]]]:
    """Rings of every (already oriented) cell, vectorised: parts -> rings -> coordinates."""
    parts, cell_of_part = shapely.get_parts(polys, return_index=True)
    rings, part_of_ring = shapely.get_rings(parts, return_index=True)
    coords, ring_of_coord = shapely.get_coordinates(rings, return_index=True)
    bounds = np.searchsorted(ring_of_coord, np.arange(len(rings) + 1)).tolist()
    flat = coords.tolist()
    out: list[list[list[list[float]]]] = [[] for _ in range(len(polys))]
    for k, cell in enumerate(cell_of_part[part_of_ring].tolist()):
        out[cell].append(flat[bounds[k] : bounds[k + 1]])
    return out


def write_shapefile_zip(cells: CellTable, name: str = "prescription") -> bytes:
    """Flat zip bytes of the prescription Shapefile (see module docstring)."""
    if not name or any(c in name for c in "/\\") or len(name) > 64:
        raise FormatError(f"bad shapefile base name {name!r}")
    shp, shx, dbf = io.BytesIO(), io.BytesIO(), io.BytesIO()
    w = pyshp.Writer(shp=shp, shx=shx, dbf=dbf, shapeType=pyshp.POLYGON, encoding="utf-8")
    w.field("SEQ", "N", 10, 0)
    w.field("SWATH", "N", 6, 0)
    w.field("RATE", "N", 12, 2)
    w.field("UNIT", "C", 8)
    w.field("FLAG", "C", 80)
    w.field("AREA_M2", "N", 14, 2)
    # exterior rings clockwise, holes counter-clockwise (Shapefile spec)
    polys = shapely.orient_polygons(round_coords(cells.polygons_wgs84(), 9), exterior_cw=True)
    flags = flag_strings(cells.flags)
    all_rings = _rings_per_cell(polys)
    for i in range(len(cells)):
        rings = all_rings[i]
        if not rings:
            raise FormatError(f"cell {int(cells.seq[i])} has an empty polygon")
        w.poly(rings)
        w.record(
            int(cells.seq[i]),
            int(cells.swath[i]),
            round(float(cells.rate_kg_ha[i]), 2),
            "kg/ha",
            flags[i],
            round(float(cells.area_m2[i]), 2),
        )
    w.close()
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr(f"{name}.shp", shp.getvalue())
        z.writestr(f"{name}.shx", shx.getvalue())
        z.writestr(f"{name}.dbf", dbf.getvalue())
        z.writestr(f"{name}.prj", WGS84_PRJ)
        z.writestr(f"{name}.cpg", "UTF-8")
    return out.getvalue()
