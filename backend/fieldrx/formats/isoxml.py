"""ISO 11783-10 task data (TASKDATA.zip) that ISOBUS terminals load.

Two variants, both a zip holding ``TASKDATA/TASKDATA.XML`` (version 4.3):

* ``write_isoxml_grid``: a type-2 grid (``GRD`` + binary ``GRD00001.BIN``).
  Each grid cell holds one little-endian int32: DDI 0006 "Setpoint Mass Per
  Area Application Rate" in mg/m^2 (1 kg/ha = 10^6 mg / 10^4 m^2 = 100 mg/m^2);
  a liquid prescribed in l/ha carries DDI 0001 "Setpoint Volume Per Area" instead
  (``Setpoint``).
  The grid origin (GRD A/B) is its south-west corner, row 0 is the southern
  row and each row runs west to east. The cell size in degrees comes from a
  size in metres at the field's latitude; each grid cell takes the rate of the
  prescription cell covering its centre, 0 outside the field.
* ``write_isoxml_zones``: treatment zones (``TZN``) with ``PLN`` polygons:
  the cells dissolved into rate classes (``formats.zones.dissolve_zones``:
  a user-set class count, small patches merged, the polygon count bounded
  for terminals), one zone per class.

Coordinates carry at most 9 fraction digits (the XSD's limit; some commercial
exports fail validation with more); polygons are snapped to that precision
with GEOS so they are valid in the written coordinates (``zones.snap_valid``).
The XML is written with ElementTree and checked against the ISO 11783-10 XSD
in the tests (xmlschema) and read back
with the ``isoxml`` package.
"""

from __future__ import annotations

import io
import math
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
from fieldrx_edge.rateunits.registry import RateUnitError, unit_of
from pyproj import Geod

from fieldrx.agronomy.cells import CellTable
from fieldrx.formats import FormatError
from fieldrx.formats.zones import (
    DEFAULT_MAX_POLYGONS,
    DEFAULT_ZONE_CLASSES,
    ZoneSummary,
    dissolve_zones,
    polygon_parts,
    snap_valid,
)
from fieldrx.geo.crs import lonlat_to_utm_xy, plane_area_m2

DDI_SETPOINT_MASS_PER_AREA = 0x0006  # mg/m^2
MG_M2_PER_KG_HA = 100.0
MAX_GRID_CELLS = 25_000_000
SOFTWARE = ("FieldRx", "0.1.0")
_GEOD = Geod(ellps="WGS84")


def rate_to_mg_m2(rate_kg_ha: np.ndarray) -> np.ndarray:
    """kg/ha -> integer mg/m^2 (DDI 0006 resolution 1 mg/m^2 = 0.01 kg/ha)."""
    return np.rint(np.asarray(rate_kg_ha, dtype=float) * MG_M2_PER_KG_HA).astype(np.int64)


@dataclass(frozen=True)
class Setpoint:
    """Which setpoint DDI a task carries and how a kg/ha rate becomes its integer value.

    The prescription's rate unit (``fieldrx_edge.rateunits``) decides: kg/ha goes out as
    mass per area (DDI 0006, mg/m^2); a liquid prescribed in l/ha as volume per area (DDI
    0001, 0.01 mm^3/m^2) with l/ha = kg/ha / density, so a sprayer's volume-rate controller
    takes it without a conversion at the terminal. ``kg_per_unit``: kg/ha in 1 unit/ha
    (from the product lot: a liquid's density).
    """

    unit: str = "kg/ha"
    kg_per_unit: float = 1.0

    @property
    def ddi(self) -> int:
        return unit_of(self.unit).ddi_setpoint

    def shown(self, rate_kg_ha: float) -> float:
        return rate_kg_ha / self.kg_per_unit

    def values(self, rate_kg_ha: np.ndarray) -> np.ndarray:
        per_unit = np.asarray(rate_kg_ha, dtype=float) / self.kg_per_unit
        return np.rint(per_unit * unit_of(self.unit).bits_per_unit).astype(np.int64)


MASS = Setpoint()


def unit_setpoint(unit: str, lot: dict[str, float] | None) -> Setpoint:
    """The setpoints of a prescription in ``unit`` whose product lot is ``lot``."""
    u = unit_of(unit)
    try:
        return Setpoint(u.name, u.kg_per_unit(u.check_lot(lot)))
    except RateUnitError as exc:
        raise FormatError(str(exc)) from None


def deg(v: float) -> str:
    """Decimal degrees with 9 fraction digits (XSD fractionDigits 9)."""
    s = f"{v:.9f}"
    return "0.000000000" if s == "-0.000000000" else s


def taskdata_root() -> ET.Element:
    return ET.Element(
        "ISO11783_TaskData",
        {
            "VersionMajor": "4",
            "VersionMinor": "3",
            "ManagementSoftwareManufacturer": SOFTWARE[0],
            "ManagementSoftwareVersion": SOFTWARE[1],
            "DataTransferOrigin": "1",  # FMIS
        },
    )


def line_string_element(parent: ET.Element, ring: Any, kind: str) -> None:
    lsg = ET.SubElement(parent, "LSG", {"A": kind})
    coords = np.asarray(ring.coords)
    for lon, lat in coords[:, :2]:
        ET.SubElement(lsg, "PNT", {"A": "2", "C": deg(lat), "D": deg(lon)})


def polygon_element(
    parent: ET.Element, poly: Any, pln_type: str, designator: str | None = None
) -> None:
    attrs = {"A": pln_type}
    if designator:
        attrs["B"] = designator[:32]
    pln = ET.SubElement(parent, "PLN", attrs)
    p = shapely.orient_polygons(poly, exterior_cw=False)
    line_string_element(pln, p.exterior, "1")
    for h in p.interiors:
        line_string_element(pln, h, "2")


def partfield_area_m2(cells: CellTable, boundary_wgs84: Any) -> float:
    """The partfield's area (PFD D, m^2): the field's, in its UTM plane like every FieldRx
    area (``geo.crs.AREA_BASIS``); the cells' total only when no boundary is known."""
    if boundary_wgs84 is None or cells.epsg <= 0:
        return cells.total_area_m2
    return plane_area_m2(boundary_wgs84, cells.epsg)


def task_name(text: str, limit: int = 32) -> str:
    """A designator cut to ISO 11783-10's 32 characters at a word boundary (a terminal
    showed "Rx Home field north of the ba")."""
    text = " ".join(text.split())
    if len(text) <= limit:
        return text
    cut = text[:limit]
    if text[limit] != " " and " " in cut[limit // 2 :]:
        cut = cut.rsplit(" ", 1)[0]
    return cut.rstrip()


def _common(
    field_name: str, field_area_m2: float, boundary_wgs84: Any, product_name: str
) -> tuple[ET.Element, ET.Element]:
    root = taskdata_root()
    pfd = ET.SubElement(
        root,
        "PFD",
        {"A": "PFD1", "C": (field_name or "field")[:32], "D": str(int(round(field_area_m2)))},
    )
    if boundary_wgs84 is not None:
        for part in polygon_parts(snap_valid(boundary_wgs84)):
            polygon_element(pfd, part, "1", field_name)
    ET.SubElement(root, "PDT", {"A": "PDT1", "B": (product_name or "fertilizer")[:32]})
    tsk = ET.SubElement(
        root,
        "TSK",
        {
            "A": "TSK1",
            "B": task_name(f"Rx {field_name}" if field_name else "FieldRx prescription"),
            "E": "PFD1",
            "G": "1",  # planned
            "H": "0",  # default zone: no rate
            "I": "0",  # position lost: no rate
            "J": "0",  # out of field: no rate
        },
    )
    return root, tsk


def _tzn(parent: ET.Element, code: int, designator: str) -> ET.Element:
    return ET.SubElement(parent, "TZN", {"A": str(code), "B": designator[:32]})


def _pdv(tzn: ET.Element, value: int, ddi: int = DDI_SETPOINT_MASS_PER_AREA) -> None:
    ET.SubElement(tzn, "PDV", {"A": f"{ddi:04X}", "B": str(int(value)), "C": "PDT1"})


def xml_bytes(root: ET.Element) -> bytes:
    ET.indent(root, space=" ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


def taskdata_zip(files: dict[str, bytes]) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in files.items():
            z.writestr(f"TASKDATA/{name}", data)
    return out.getvalue()


@dataclass
class GridSpec:
    """The ISO grid geometry: south-west origin, cell size in degrees, rows x columns."""

    south: float
    west: float
    cell_north_deg: float
    cell_east_deg: float
    rows: int
    cols: int

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Lon/lat of every cell centre, shape (rows, cols); row 0 south."""
        lat = self.south + (np.arange(self.rows) + 0.5) * self.cell_north_deg
        lon = self.west + (np.arange(self.cols) + 0.5) * self.cell_east_deg
        lon2, lat2 = np.meshgrid(lon, lat)
        return lon2, lat2


def grid_spec(bounds_wgs84: tuple[float, float, float, float], cell_m: float) -> GridSpec:
    """Cells of about ``cell_m`` x ``cell_m`` metres at the centre latitude, covering the bounds."""
    if not (math.isfinite(cell_m) and cell_m > 0):
        raise FormatError(f"ISO grid cell size must be > 0 m, got {cell_m}")
    w, s, e, n = bounds_wgs84
    lat_c, lon_c = 0.5 * (s + n), 0.5 * (w + e)
    # metres per degree of latitude / longitude at the field (ellipsoidal)
    _, _, m_lat = _GEOD.inv(lon_c, lat_c - 0.005, lon_c, lat_c + 0.005)
    _, _, m_lon = _GEOD.inv(lon_c - 0.005, lat_c, lon_c + 0.005, lat_c)
    dlat = float(f"{cell_m / (m_lat / 0.01):.12g}")
    dlon = float(f"{cell_m / (m_lon / 0.01):.12g}")
    if dlat > 1.0 or dlon > 1.0:
        raise FormatError("ISO grid cells may not exceed 1 degree")
    south = math.floor(s * 1e9) / 1e9
    west = math.floor(w * 1e9) / 1e9
    rows = max(1, math.ceil((n - south) / dlat))
    cols = max(1, math.ceil((e - west) / dlon))
    if rows * cols > MAX_GRID_CELLS:
        raise FormatError(
            f"ISO grid would have {rows * cols} cells (> {MAX_GRID_CELLS}): use a larger cell size"
        )
    return GridSpec(south, west, dlat, dlon, rows, cols)


def default_grid_cell_m(cells: CellTable) -> float:
    """Half the typical cell side (sqrt of the median area), within 0.5..10 m."""
    if len(cells) == 0:
        return 1.0
    return float(min(10.0, max(0.5, math.sqrt(float(np.median(cells.area_m2))) / 2.0)))


def rasterise_rates(cells: CellTable, spec: GridSpec) -> np.ndarray:
    """Rate of the prescription cell covering each grid-cell centre (rows x cols), 0 outside.

    Centres are placed in the cells' UTM zone and located with an STRtree; a
    centre on a shared edge takes the cell earliest in path order.
    """
    lon, lat = spec.centres()
    x, y = lonlat_to_utm_xy(lon.ravel(), lat.ravel(), cells.epsg)
    out = np.zeros(lon.size)
    if len(cells):
        tree = shapely.STRtree(cells.polygons_utm)
        pi, ci = tree.query(shapely.points(x, y), predicate="intersects")
        if len(pi):
            order = np.lexsort((ci, pi))  # per point, smallest cell index first
            pi, ci = pi[order], ci[order]
            first = np.ones(len(pi), dtype=bool)
            first[1:] = pi[1:] != pi[:-1]
            out[pi[first]] = cells.rate_kg_ha[ci[first]]
    return out.reshape(spec.rows, spec.cols)


def write_isoxml_grid(
    cells: CellTable,
    field_name: str = "",
    boundary_wgs84: Any = None,
    product_name: str = "fertilizer",
    grid_cell_m: float | None = None,
    setpoint: Setpoint = MASS,
) -> bytes:
    """TASKDATA.zip with a type-2 grid of DDI 0006 setpoints (see module docstring), or
    another unit's (``setpoint``: DDI 0001 for l/ha)."""
    if len(cells) == 0:
        raise FormatError("prescription has no cells")
    cell_m = default_grid_cell_m(cells) if grid_cell_m is None else float(grid_cell_m)
    bounds = (
        tuple(shapely.total_bounds(cells.polygons_wgs84()))
        if boundary_wgs84 is None
        else tuple(boundary_wgs84.bounds)
    )
    spec = grid_spec(bounds, cell_m)
    values = setpoint.values(rasterise_rates(cells, spec))
    if values.max(initial=0) > np.iinfo(np.int32).max:
        raise FormatError("a rate is too large for an ISO 11783 setpoint")
    binary = values.astype("<i4").tobytes(order="C")
    root, tsk = _common(
        field_name, partfield_area_m2(cells, boundary_wgs84), boundary_wgs84, product_name
    )
    _pdv(_tzn(tsk, 0, "no rate"), 0, setpoint.ddi)
    _pdv(_tzn(tsk, 1, "prescription grid"), 0, setpoint.ddi)
    ET.SubElement(
        tsk,
        "GRD",
        {
            "A": deg(spec.south),
            "B": deg(spec.west),
            "C": np.format_float_positional(spec.cell_north_deg),
            "D": np.format_float_positional(spec.cell_east_deg),
            "E": str(spec.cols),
            "F": str(spec.rows),
            "G": "GRD00001",
            "H": str(len(binary)),
            "I": "2",
            "J": "1",
        },
    )
    return taskdata_zip({"TASKDATA.XML": xml_bytes(root), "GRD00001.BIN": binary})


def write_isoxml_zones(
    cells: CellTable,
    field_name: str = "",
    boundary_wgs84: Any = None,
    product_name: str = "fertilizer",
    n_classes: int = DEFAULT_ZONE_CLASSES,
    max_polygons: int = DEFAULT_MAX_POLYGONS,
    min_patch_m2: float | None = None,
    setpoint: Setpoint = MASS,
) -> tuple[bytes, ZoneSummary]:
    """TASKDATA.zip with one treatment zone (TZN + PLN polygons) per rate class.

    Zone 0 is "no rate" (default, position lost and out of field); zones
    1..k carry their class's dissolved polygons and a DDI 0006 setpoint. The
    summary says how the cells were simplified (the API shows it).
    """
    zones, summary = dissolve_zones(cells, n_classes, max_polygons, min_patch_m2)
    root, tsk = _common(
        field_name, partfield_area_m2(cells, boundary_wgs84), boundary_wgs84, product_name
    )
    _pdv(_tzn(tsk, 0, "no rate"), 0, setpoint.ddi)
    for code, zone in enumerate(zones, start=1):
        value = int(setpoint.values(np.asarray([zone.rate_kg_ha]))[0])
        tzn = _tzn(tsk, code, f"{setpoint.shown(zone.rate_kg_ha):.2f} {setpoint.unit}")
        for part in zone.polygons:
            polygon_element(tzn, part, "2")
        _pdv(tzn, value, setpoint.ddi)
    return taskdata_zip({"TASKDATA.XML": xml_bytes(root)}), summary
