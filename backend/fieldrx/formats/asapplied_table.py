"""Other terminals' as-applied Shapefile / CSV in, with an attribute-mapping step.

Terminals export as-applied logs as point (or polygon) Shapefiles or CSV
tables with a rate column whose name and unit vary. ``read_table`` reads the
rows (a zipped Shapefile through the bounded archive reader, or a CSV),
``table_columns`` lists the numeric columns with suggestions for the
preview, and ``to_timelog`` turns the mapped rows into the same ``TimeLog``
an ISO 11783-10 TimeLog becomes, so one storing path
(``services.timelog_import.store_timelogs``) serves both.

Mapping: ``rate_column`` and its ``unit`` (kg/ha, lb/ac, g/m2, t/ha),
optional ``target_column`` (same unit), ``work_state_column`` (non-zero =
implement working; default: working where the rate is > 0), ``speed_column`` with
``speed_unit`` (m/s, km/h, mph), ``time_column`` (ISO 8601 or epoch
seconds) and, for CSV, ``lon_column``/``lat_column``. Without times the
rows are taken as logged every ``interval_s`` seconds in file order; without
speeds the speed is the distance to the next row over the time between them.
Polygon records stand at their inside point.
"""

from __future__ import annotations

import csv
import datetime as dt
import io
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapefile as pyshp
import shapely
from pyproj import CRS, Geod, Transformer
from pyproj.exceptions import CRSError
from shapely.geometry import shape

from fieldrx.formats import FormatError
from fieldrx.formats.archive import read_zip
from fieldrx.formats.rx_shapefile import UNITS
from fieldrx.formats.timelog import TimeLog

MAX_ROWS = 2_000_000
SPEED_UNITS = {"m/s": 1.0, "km/h": 1 / 3.6, "mph": 0.44704}
SUGGEST = {
    "rate_column": ("APPLIED", "APPL_RATE", "AppliedRate", "RATE", "Rate", "ACTUAL"),
    "target_column": ("TARGET", "TGT_RATE", "TargetRate", "Target_Rat"),
    "speed_column": ("SPEED", "SPEED_MS", "Speed", "VEHICLSPEED"),
    "time_column": ("TIME", "Time", "TIMESTAMP", "DATETIME", "IsoTime"),
    "work_state_column": ("DOWN", "WORKSTATE", "WorkState", "ON", "Active"),
    "lon_column": ("lon", "LON", "Longitude", "LONGITUDE", "x", "X"),
    "lat_column": ("lat", "LAT", "Latitude", "LATITUDE", "y", "Y"),
}
_GEOD = Geod(ellps="WGS84")


@dataclass
class Table:
    name: str
    rows: list[dict[str, Any]]
    points: list[tuple[float, float]] | None  # lon/lat per row (Shapefile), None for CSV


def _shapefile(name: str, files: dict[str, bytes]) -> Table:
    shps = [n for n in files if n.lower().endswith(".shp")]
    if len(shps) != 1:
        raise FormatError(f"{name}: the zip must hold one .shp, found {len(shps)}")
    base = shps[0][:-4]
    lower = {k.lower(): v for k, v in files.items()}
    dbf = lower.get((base + ".dbf").lower())
    if dbf is None:
        raise FormatError(f"{name}: {base}.dbf is missing")
    prj = lower.get((base + ".prj").lower())
    try:
        r = pyshp.Reader(
            shp=io.BytesIO(files[shps[0]]),
            shx=io.BytesIO(lower[(base + ".shx").lower()])
            if (base + ".shx").lower() in lower
            else None,
            dbf=io.BytesIO(dbf),
            encodingErrors="replace",
        )
        records = list(r.iterShapeRecords())
    except Exception as exc:  # pyshp raises its own and struct errors on corrupt files
        raise FormatError(f"{name}: cannot read the shapefile ({exc})") from exc
    if len(records) > MAX_ROWS:
        raise FormatError(f"{name}: more than {MAX_ROWS} records")
    tr = None
    if prj:
        try:
            crs = CRS.from_wkt(prj.decode("utf-8", "replace"))
        except CRSError as exc:
            raise FormatError(f"{name}: cannot understand {base}.prj ({exc})") from exc
        if not crs.equals(CRS.from_epsg(4326), ignore_axis_order=True):
            tr = Transformer.from_crs(crs, 4326, always_xy=True)
    fields = [f[0] for f in r.fields[1:]]
    rows, pts = [], []
    for i, sr in enumerate(records):
        if sr.shape.shapeType == pyshp.NULL:
            raise FormatError(f"{name}: record {i} has no geometry")
        g = shape(sr.shape.__geo_interface__)
        p = g if g.geom_type == "Point" else shapely.point_on_surface(g)
        x, y = p.x, p.y
        if tr is not None:
            x, y = tr.transform(x, y)
        if not (-180 <= x <= 180 and -90 <= y <= 90):
            raise FormatError(f"{name}: record {i} at ({x}, {y}) is not lon/lat; add its .prj")
        pts.append((float(x), float(y)))
        rows.append(dict(zip(fields, list(sr.record), strict=False)))
    return Table(name, rows, pts)


def read_table(filename: str, data: bytes) -> Table:
    """Rows of a zipped Shapefile (``.zip``) or a CSV (``.csv``, ``,`` or ``;``)."""
    low = (filename or "").lower()
    if low.endswith(".zip"):
        return _shapefile(filename, read_zip(data))
    if low.endswith((".csv", ".txt")):
        try:
            text = data.decode("utf-8-sig")
        except UnicodeDecodeError:
            text = data.decode("latin-1")
        delim = (
            ";" if text.split("\n", 1)[0].count(";") > text.split("\n", 1)[0].count(",") else ","
        )
        rows = list(csv.DictReader(io.StringIO(text), delimiter=delim))
        if len(rows) > MAX_ROWS:
            raise FormatError(f"{filename}: more than {MAX_ROWS} rows")
        return Table(filename, rows, None)
    raise FormatError(f"unsupported file {filename!r}: expected a zipped Shapefile or a .csv")


def _num(v: Any) -> float | None:
    if v is None or isinstance(v, bool):
        return None
    try:
        x = float(str(v).strip().replace(",", ".")) if not isinstance(v, int | float) else float(v)
    except ValueError:
        return None
    return x if math.isfinite(x) else None


def table_columns(table: Table) -> dict[str, Any]:
    """Columns (numeric ones with min/max) and a suggestion per mapping field."""
    names = list(table.rows[0]) if table.rows else []
    numeric = {}
    for n in names:
        vals = [_num(r.get(n)) for r in table.rows]
        if vals and all(v is not None for v in vals):
            nums = [v for v in vals if v is not None]
            numeric[n] = {"min": min(nums), "max": max(nums)}
    suggest = {}
    for key, cands in SUGGEST.items():
        suggest[key] = next((c for c in cands if c in names), None)
    return {"columns": names, "numeric": numeric, "suggested": suggest, "rows": len(table.rows)}


def _time(v: Any, i: int, col: str) -> float:
    x = _num(v)
    if x is not None:
        return x
    try:
        t = dt.datetime.fromisoformat(str(v).strip().replace("Z", "+00:00"))
    except ValueError:
        raise FormatError(f"row {i}: {col}={v!r} is neither ISO 8601 nor epoch seconds") from None
    return (t if t.tzinfo else t.replace(tzinfo=dt.UTC)).timestamp()


@dataclass(frozen=True)
class ColumnMap:
    """The mapping step: which columns of the table hold what, in which units (see the
    module docstring); the column names are checked against the table by ``to_timelog``."""

    rate_column: str
    unit: str = "kg/ha"
    target_column: str | None = None
    speed_column: str | None = None
    speed_unit: str = "m/s"
    time_column: str | None = None
    work_state_column: str | None = None
    lon_column: str | None = None
    lat_column: str | None = None
    interval_s: float = 1.0


def _column(table: Table, c: str, what: str) -> np.ndarray:
    """Column ``c`` as numbers; a row that is not a number is an error naming it."""
    out = np.empty(len(table.rows))
    for i, r in enumerate(table.rows):
        v = _num(r.get(c))
        if v is None:
            raise FormatError(f"row {i}: {c}={r.get(c)!r} is not a number ({what})")
        out[i] = v
    return out


def _check_mapping(table: Table, m: ColumnMap) -> None:
    if m.unit not in UNITS:
        raise FormatError(f"unit {m.unit!r} is not one of {sorted(UNITS)}")
    if m.speed_unit not in SPEED_UNITS:
        raise FormatError(f"speed unit {m.speed_unit!r} is not one of {sorted(SPEED_UNITS)}")
    if not (math.isfinite(m.interval_s) and m.interval_s > 0):
        raise FormatError(f"interval_s must be > 0, got {m.interval_s}")
    names = set(table.rows[0]) if table.rows else set()
    mapped = {
        "rate_column": m.rate_column,
        "target_column": m.target_column,
        "speed_column": m.speed_column,
        "time_column": m.time_column,
        "work_state_column": m.work_state_column,
        "lon_column": m.lon_column,
        "lat_column": m.lat_column,
    }
    for key, name in mapped.items():
        if name is not None and name not in names:
            raise FormatError(f"{key} {name!r} is not a column ({sorted(names)})")
    if not table.rows:
        raise FormatError(f"{table.name}: no rows")


def _positions(table: Table, m: ColumnMap) -> tuple[np.ndarray, np.ndarray]:
    """Longitudes and latitudes of the rows: the Shapefile's points or the CSV's columns."""
    if table.points is not None:
        return (
            np.asarray([p[0] for p in table.points]),
            np.asarray([p[1] for p in table.points]),
        )
    if m.lon_column is None or m.lat_column is None:
        raise FormatError("a CSV needs lon_column and lat_column")
    lon, lat = _column(table, m.lon_column, "longitude"), _column(table, m.lat_column, "latitude")
    bad = np.flatnonzero((np.abs(lon) > 180) | (np.abs(lat) > 90))
    if len(bad):
        raise FormatError(f"row {int(bad[0])}: position is not lon/lat")
    return lon, lat


def _speeds(
    table: Table, m: ColumnMap, t: np.ndarray, lon: np.ndarray, lat: np.ndarray
) -> np.ndarray:
    """m/s per row: the speed column, else the distance to the next row over the time."""
    if m.speed_column is not None:
        return _column(table, m.speed_column, "speed") * SPEED_UNITS[m.speed_unit]
    n = len(t)
    _, _, d = _GEOD.inv(lon[:-1], lat[:-1], lon[1:], lat[1:]) if n > 1 else (0, 0, np.zeros(0))
    dts = np.diff(t)
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.where(dts > 0, np.asarray(d) / dts, 0.0)
    return np.append(v, v[-1:] if len(v) else [0.0])


def to_timelog(table: Table, mapping: ColumnMap, *, start_t: float = 0.0) -> TimeLog:
    """The mapped rows as a TimeLog (DDI 7/6 in mg/m^2, 397 in mm/s, 141 on when rate > 0)."""
    m = mapping
    _check_mapping(table, m)
    n = len(table.rows)
    lon, lat = _positions(table, m)
    factor = UNITS[m.unit]
    applied = _column(table, m.rate_column, "rate") * factor
    if (applied < 0).any():
        raise FormatError(f"row {int(np.flatnonzero(applied < 0)[0])}: negative rate")
    if m.time_column is not None:
        tc = m.time_column
        t = np.asarray([_time(r.get(tc), i, tc) for i, r in enumerate(table.rows)])
    else:
        t = start_t + m.interval_s * np.arange(n)
    speed = _speeds(table, m, t, lon, lat)
    values = {
        7: np.rint(applied * 100.0),
        397: np.rint(speed * 1000.0),
        141: (applied > 0).astype(float)
        if m.work_state_column is None
        else (_column(table, m.work_state_column, "work state") != 0).astype(float),
    }
    if m.target_column is not None:
        values[6] = np.rint(_column(table, m.target_column, "target") * factor * 100.0)
    return TimeLog(
        name=table.name, t=t, lat=lat, lon=lon, status=np.ones(n), values=values, ignored_ddis=[]
    )
