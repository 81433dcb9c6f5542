"""Zipped Shapefile for farm software (Climate FieldView, Raven, Ag Leader, JD Ops Center).

``<name>.shp/.shx/.dbf/.prj/.cpg`` with WGS84 polygons (exterior rings
clockwise as the Shapefile spec wants), snapped to 9 decimals so they are
valid as written (``zones.snap_valid``). Written with pyshp. Profiles
(``PROFILES``):

* ``cells`` (default): one polygon per cell, numeric ``RATE`` and ``UNIT``
  ("kg/ha") plus ``SEQ``, ``SWATH``, ``FLAG`` and ``AREA_M2``; a flat zip.
  For GIS and FMIS, not terminals (tens of thousands of polygons).
* ``deere``: John Deere Operations Center / Gen4 displays: the files inside
  an ``Rx/`` folder of the zip, rate zones (``zones.dissolve_zones``).
* ``fieldview``, ``raven``, ``agleader``, ``trimble``: rate zones in a flat
  zip; FieldView documents at most 100 zones, the default polygon limit.

Zone profiles write one single-part Polygon per record (``ZONE``, ``RATE``,
``UNIT``, ``AREA_M2``): multi-part records are where terminals disagree.
"""

from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass

import numpy as np
import shapefile as pyshp
import shapely

from fieldrx.agronomy.cells import CellTable, flag_strings
from fieldrx.formats import FormatError
from fieldrx.formats.zones import (
    DEFAULT_MAX_POLYGONS,
    DEFAULT_ZONE_CLASSES,
    ZoneSummary,
    dissolve_zones,
    snap_valid,
)

WGS84_PRJ = (
    'GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,298.257223563]],'
    'PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]]'
)


@dataclass(frozen=True)
class Profile:
    """How one family of readers wants the prescription Shapefile."""

    folder: str  # "" = flat zip
    zones: bool  # dissolve cells into rate zones
    max_polygons: int


PROFILES = {
    "cells": Profile("", False, 0),
    "deere": Profile("Rx/", True, DEFAULT_MAX_POLYGONS),
    "fieldview": Profile("", True, 100),
    "raven": Profile("", True, DEFAULT_MAX_POLYGONS),
    "agleader": Profile("", True, DEFAULT_MAX_POLYGONS),
    "trimble": Profile("", True, DEFAULT_MAX_POLYGONS),
}


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


def _check_name(name: str) -> None:
    if not name or any(c in name for c in "/\\") or len(name) > 64:
        raise FormatError(f"bad shapefile base name {name!r}")


def _zip(name: str, folder: str, shp: bytes, shx: bytes, dbf: bytes) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr(f"{folder}{name}.shp", shp)
        z.writestr(f"{folder}{name}.shx", shx)
        z.writestr(f"{folder}{name}.dbf", dbf)
        z.writestr(f"{folder}{name}.prj", WGS84_PRJ)
        z.writestr(f"{folder}{name}.cpg", "UTF-8")
    return out.getvalue()


def write_shapefile_zip(cells: CellTable, name: str = "prescription") -> bytes:
    """Flat zip bytes of the per-cell prescription Shapefile (profile ``cells``)."""
    _check_name(name)
    shp, shx, dbf = io.BytesIO(), io.BytesIO(), io.BytesIO()
    w = pyshp.Writer(shp=shp, shx=shx, dbf=dbf, shapeType=pyshp.POLYGON, encoding="utf-8")
    w.field("SEQ", "N", 10, 0)
    w.field("SWATH", "N", 6, 0)
    w.field("RATE", "N", 12, 2)
    w.field("UNIT", "C", 8)
    w.field("FLAG", "C", 80)
    w.field("AREA_M2", "N", 14, 2)
    # valid in the written coordinates; exterior rings clockwise, holes ccw (Shapefile spec)
    polys = shapely.orient_polygons(snap_valid(cells.polygons_wgs84()), exterior_cw=True)
    flags = flag_strings(cells.flags)
    all_rings = _rings_per_cell(polys)
    for i in range(len(cells)):
        rings = all_rings[i]
        if not rings:
            raise FormatError(
                f"cell {int(cells.seq[i])} is narrower than 0.1 mm: nothing left to write"
            )
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
    return _zip(name, "", shp.getvalue(), shx.getvalue(), dbf.getvalue())


def write_shapefile_zones_zip(
    cells: CellTable,
    name: str = "prescription",
    profile: str = "deere",
    n_classes: int = DEFAULT_ZONE_CLASSES,
    max_polygons: int | None = None,
) -> tuple[bytes, ZoneSummary]:
    """Rate-zone Shapefile for a terminal profile (see module doc) and how it was dissolved."""
    _check_name(name)
    prof = PROFILES.get(profile)
    if prof is None or not prof.zones:
        zoned = sorted(k for k, p in PROFILES.items() if p.zones)
        raise FormatError(f"unknown zone profile {profile!r} (expected one of {zoned})")
    limit = prof.max_polygons if max_polygons is None else min(max_polygons, prof.max_polygons)
    zones, summary = dissolve_zones(cells, n_classes, limit)
    shp, shx, dbf = io.BytesIO(), io.BytesIO(), io.BytesIO()
    w = pyshp.Writer(shp=shp, shx=shx, dbf=dbf, shapeType=pyshp.POLYGON, encoding="utf-8")
    w.field("ZONE", "N", 6, 0)
    w.field("RATE", "N", 12, 2)
    w.field("UNIT", "C", 8)
    w.field("AREA_M2", "N", 14, 2)
    for k, zone in enumerate(zones, start=1):
        for part in zone.polygons:
            p = shapely.orient_polygons(part, exterior_cw=True)
            rings = [list(map(list, p.exterior.coords))]
            rings += [list(map(list, r.coords)) for r in p.interiors]
            w.poly(rings)
            w.record(k, zone.rate_kg_ha, "kg/ha", round(_area_m2(part), 2))
    w.close()
    return _zip(name, prof.folder, shp.getvalue(), shx.getvalue(), dbf.getvalue()), summary


def _area_m2(poly_wgs84: object) -> float:
    from pyproj import Geod

    area, _ = Geod(ellps="WGS84").geometry_area_perimeter(poly_wgs84)
    return abs(float(area))
