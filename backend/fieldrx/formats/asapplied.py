"""As-applied data out: ISO 11783-10 task with a TimeLog, and a points + cells Shapefile.

Inputs are plain arrays (``AsAppliedPoints``: one row per telemetry record
with a position) and the per-cell rows of the job report
(``fleet.reports.build_report``; seed 001 eq. 17-18), so this module does no
database work.

ISOXML (``write_asapplied_isoxml``), a zip with ``TASKDATA/``:

* ``TASKDATA.XML`` (V4.3, valid against ISO11783_TaskFile_V4-3.xsd): a
  device ``DVC1`` (one element ``DET1`` with process data for the logged
  DDIs), the partfield boundary, the product, and a completed task (G=4)
  whose ``TIM`` (D=4 effective, start and stop in UTC) carries the totals:
  DDI 0x0160 (352) "Application Total Mass in gram", DDI 0x0074 (116)
  "Total Area" m^2 (area of the cells that received product) and DDI 0x0077
  (119) "Effective Total Time" s. ``TLG00001`` references the time log.
* ``TLG00001.XML``, the header (valid against ISO11783_TimeLog_V4-3.xsd):
  ``TIM`` with empty A (value in the binary), ``PTN`` with empty north/east/
  status, and ``DLV`` for DDI 6 setpoint and 7 actual mass per area
  (mg/m^2 = 100 x kg/ha), 397 actual speed (mm/s) and 141 actual work state
  (1 on, 0 off).
* ``TLG00001.BIN``: per record, little-endian (ISO 11783-10 Annex D): uint32
  ms since midnight UTC, uint16 days since 1980-01-01, int32 north and east in
  1e-7 degree, uint8 position status (1 = GNSS fix), uint8 number of values,
  then (uint8 DLV index, int32 value) for every DLV.

Shapefile (``write_asapplied_shapefile_zip``): ``<stem>.shp`` the per-cell
polygons (``SEQ``, ``TARGET``, ``APPLIED``, masses, ``ACCURACY`` eq. 18,
``UNIT`` kg/ha) and ``<stem>_points.shp`` one point per record (``TIME``
ISO UTC, ``TARGET``, ``APPLIED``, ``SPEED_MS``, ``DOWN``, ``UNIT``).
"""

from __future__ import annotations

import datetime as dt
import io
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapefile as pyshp
import shapely

from fieldrx.formats import FormatError
from fieldrx.formats.isoxml import (
    polygon_element,
    rate_to_mg_m2,
    task_name,
    taskdata_root,
    taskdata_zip,
    xml_bytes,
)
from fieldrx.formats.shapefile import WGS84_PRJ
from fieldrx.formats.shp_points import DbfColumn, point_shapefile
from fieldrx.formats.zones import polygon_parts, snap_valid

DDI_SETPOINT_MASS_RATE = 0x0006  # mg/m^2
DDI_ACTUAL_MASS_RATE = 0x0007  # mg/m^2
DDI_ACTUAL_SPEED = 0x018D  # 397, mm/s
DDI_WORK_STATE = 0x008D  # 141, 1 = on
DDI_TOTAL_MASS_G = 0x0160  # 352, g
DDI_TOTAL_AREA = 0x0074  # 116, m^2
DDI_EFFECTIVE_TIME = 0x0077  # 119, s
LOGGED = (DDI_SETPOINT_MASS_RATE, DDI_ACTUAL_MASS_RATE, DDI_ACTUAL_SPEED, DDI_WORK_STATE)
EPOCH_1980 = dt.date(1980, 1, 1)


@dataclass
class AsAppliedPoints:
    """One row per record with a position (time order); rates in kg/ha, speed in m/s."""

    t: np.ndarray
    lon: np.ndarray
    lat: np.ndarray
    target_kg_ha: np.ndarray
    applied_kg_ha: np.ndarray
    speed_m_s: np.ndarray
    down: np.ndarray

    def __len__(self) -> int:
        return len(self.t)


@dataclass
class AsAppliedTotals:
    applied_total_kg: float
    area_applied_m2: float
    time_worked_s: float
    first_t: float | None
    last_t: float | None
    # the partfield's area (PFD D): the field's stored area, in its UTM plane like the
    # cells' (``geo.crs.AREA_BASIS``), so D and TIM's DDI 116 share one basis
    field_area_m2: float = 0.0


def _when(t: float) -> str:
    return dt.datetime.fromtimestamp(t, dt.UTC).strftime("%Y-%m-%dT%H:%M:%S")


def _hex(ddi: int) -> str:
    return f"{ddi:04X}"


def _device(root: ET.Element) -> None:
    dvc = ET.SubElement(
        root,
        "DVC",
        {
            "A": "DVC1",
            "B": "FieldRx edge agent",
            "D": "A000860025000000",  # ISO NAME (self-configurable, FMIS-assigned)
            "F": "46525800000000",  # structure label "FRX"
            "G": "FF000000000000",  # localization label: unknown
        },
    )
    det = ET.SubElement(
        dvc, "DET", {"A": "DET1", "B": "1", "C": "1", "D": "spreader", "E": "0", "F": "0"}
    )
    ddis = (*LOGGED, DDI_TOTAL_MASS_G, DDI_TOTAL_AREA, DDI_EFFECTIVE_TIME)
    for k in range(len(ddis)):
        ET.SubElement(det, "DOR", {"A": str(k + 2)})
    for k, ddi in enumerate(ddis):
        trigger = "16" if ddi in (DDI_TOTAL_MASS_G, DDI_TOTAL_AREA, DDI_EFFECTIVE_TIME) else "1"
        ET.SubElement(dvc, "DPD", {"A": str(k + 2), "B": _hex(ddi), "C": "1", "D": trigger})


def timelog_records(points: AsAppliedPoints) -> bytes:
    """The TLG binary (see module docstring); all values checked for their int ranges."""
    n = len(points)
    if n == 0:
        return b""
    values = np.column_stack(
        [
            rate_to_mg_m2(np.nan_to_num(points.target_kg_ha)),
            rate_to_mg_m2(np.nan_to_num(points.applied_kg_ha)),
            np.rint(np.nan_to_num(points.speed_m_s) * 1000.0).astype(np.int64),
            np.asarray(points.down, dtype=bool).astype(np.int64),
        ]
    )
    lat = np.rint(np.asarray(points.lat) * 1e7).astype(np.int64)
    lon = np.rint(np.asarray(points.lon) * 1e7).astype(np.int64)
    if np.abs(values).max() > 2**31 - 1:
        raise FormatError("an as-applied value does not fit a 32-bit ISO 11783 process value")
    # one packed record per point, built column-wise (a struct.pack and two datetimes per
    # point cost ~0.1 ms each): ms since midnight UTC, days since 1980-01-01, lat, lon
    # (1e-7 deg), then the DLV count and (DLV index, value) pairs
    names = ["ms", "days", "lat", "lon", "pos", "n"]
    formats = ["<u4", "<u2", "<i4", "<i4", "u1", "u1"]
    for k in range(len(LOGGED)):
        names += [f"k{k}", f"v{k}"]
        formats += ["u1", "<i4"]
    rec = np.zeros(n, dtype=np.dtype({"names": names, "formats": formats}, align=False))
    t_ms = np.rint(np.asarray(points.t, dtype=float) * 1000.0).astype(np.int64)
    day = t_ms // 86_400_000
    rec["ms"] = t_ms - day * 86_400_000
    rec["days"] = day - (EPOCH_1980 - dt.date(1970, 1, 1)).days
    rec["lat"], rec["lon"], rec["pos"], rec["n"] = lat, lon, 1, len(LOGGED)
    for k in range(len(LOGGED)):
        rec[f"k{k}"] = k
        rec[f"v{k}"] = values[:, k]
    return rec.tobytes()


def timelog_header() -> bytes:
    tim = ET.Element("TIM", {"A": "", "D": "4"})
    ET.SubElement(tim, "PTN", {"A": "", "B": "", "D": ""})
    for ddi in LOGGED:
        ET.SubElement(tim, "DLV", {"A": _hex(ddi), "B": "", "C": "DET1"})
    return xml_bytes(tim)


def write_asapplied_isoxml(
    points: AsAppliedPoints,
    totals: AsAppliedTotals,
    *,
    job_name: str,
    field_name: str,
    boundary_wgs84: Any,
    product_name: str,
) -> bytes:
    """TASKDATA.zip of a completed task with its TimeLog (see module docstring)."""
    if totals.first_t is None or totals.last_t is None:
        raise FormatError("the job has no as-applied records to export")
    root = taskdata_root()
    _device(root)
    pfd = ET.SubElement(root, "PFD", {"A": "PFD1", "C": (field_name or "field")[:32], "D": "0"})
    if boundary_wgs84 is not None:
        parts = polygon_parts(snap_valid(boundary_wgs84))
        pfd.set("D", str(int(round(totals.field_area_m2))))
        for part in parts:
            polygon_element(pfd, part, "1", field_name)
    ET.SubElement(root, "PDT", {"A": "PDT1", "B": (product_name or "fertilizer")[:32]})
    tsk = ET.SubElement(
        root, "TSK", {"A": "TSK1", "B": task_name(job_name or "as-applied"), "E": "PFD1", "G": "4"}
    )
    tim = ET.SubElement(
        tsk, "TIM", {"A": _when(totals.first_t), "B": _when(totals.last_t), "D": "4"}
    )
    for ddi, value in (
        (DDI_TOTAL_MASS_G, totals.applied_total_kg * 1000.0),
        (DDI_TOTAL_AREA, totals.area_applied_m2),
        (DDI_EFFECTIVE_TIME, totals.time_worked_s),
    ):
        ET.SubElement(tim, "DLV", {"A": _hex(ddi), "B": str(int(round(value))), "C": "DET1"})
    ET.SubElement(tsk, "DAN", {"A": "A000860025000000", "C": "DVC1"})
    ET.SubElement(tsk, "TLG", {"A": "TLG00001", "C": "1"})
    return taskdata_zip(
        {
            "TASKDATA.XML": xml_bytes(root),
            "TLG00001.XML": timelog_header(),
            "TLG00001.BIN": timelog_records(points),
        }
    )


@dataclass
class CellRow:
    seq: int
    swath: int
    n_records: int
    area_m2: float
    target_kg_ha: float
    applied_kg_ha: float
    m1_g: float
    m2_g: float
    accuracy_pct: float | None
    geom_wgs84: Any


def _shp_zip(files: dict[str, bytes]) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in files.items():
            z.writestr(name, data)
    return out.getvalue()


def _iso_times(t: np.ndarray) -> np.ndarray:
    """ISO 8601 UTC with milliseconds (``2026-11-28T07:02:00.100Z``) of epoch seconds."""
    ms = np.rint(np.asarray(t, dtype=float) * 1000.0).astype("datetime64[ms]")
    return np.char.add(np.datetime_as_string(ms, unit="ms"), "Z")


def _point_columns(points: AsAppliedPoints) -> list[DbfColumn]:
    """The points' attribute table: time, target / applied rate, speed, implement down."""
    return [
        DbfColumn("TIME", "C", 24, 0, _iso_times(points.t)),
        DbfColumn("TARGET", "N", 12, 2, np.asarray(points.target_kg_ha, dtype=float)),
        DbfColumn("APPLIED", "N", 12, 2, np.nan_to_num(points.applied_kg_ha)),
        DbfColumn("SPEED_MS", "N", 10, 3, np.nan_to_num(points.speed_m_s)),
        DbfColumn("DOWN", "N", 1, 0, np.asarray(points.down, dtype=bool).astype(float)),
        DbfColumn("UNIT", "C", 8, 0, np.full(len(points), "kg/ha")),
    ]


def write_asapplied_shapefile_zip(
    stem: str, cells: list[CellRow], points: AsAppliedPoints
) -> bytes:
    """Zip of the per-cell polygons and the per-record points (see module docstring)."""
    shp, shx, dbf = io.BytesIO(), io.BytesIO(), io.BytesIO()
    with pyshp.Writer(shp=shp, shx=shx, dbf=dbf, shapeType=pyshp.POLYGON) as w:
        for name in ("SEQ", "SWATH", "NREC"):
            w.field(name, "N", 10, 0)
        for name in ("AREA_M2", "TARGET", "APPLIED", "M1_G", "M2_G", "ACCURACY"):
            w.field(name, "N", 16, 4)
        w.field("UNIT", "C", 8)
        # one GEOS call for every cell (a call per cell was ~0.3 ms each)
        snapped = snap_valid(np.array([c.geom_wgs84 for c in cells], dtype=object))
        for c, g in zip(cells, snapped, strict=True):
            parts = polygon_parts(g)
            if not parts:
                continue
            rings = []
            for p in parts:
                p = shapely.orient_polygons(p, exterior_cw=True)
                rings.append([list(xy) for xy in p.exterior.coords])
                rings.extend([list(xy) for xy in h.coords] for h in p.interiors)
            w.poly(rings)
            w.record(
                c.seq,
                c.swath,
                c.n_records,
                c.area_m2,
                c.target_kg_ha,
                c.applied_kg_ha,
                c.m1_g,
                c.m2_g,
                c.accuracy_pct if c.accuracy_pct is not None else 0.0,
                "kg/ha",
            )
    pts = point_shapefile(points.lon, points.lat, _point_columns(points))
    files = {}
    for name, (shp_io, shx_io, dbf_io) in (
        (stem, (shp, shx, dbf)),
        (f"{stem}_points", tuple(io.BytesIO(b) for b in pts)),
    ):
        files[f"{name}.shp"] = shp_io.getvalue()
        files[f"{name}.shx"] = shx_io.getvalue()
        files[f"{name}.dbf"] = dbf_io.getvalue()
        files[f"{name}.prj"] = WGS84_PRJ.encode()
        files[f"{name}.cpg"] = b"UTF-8"
    return _shp_zip(files)
