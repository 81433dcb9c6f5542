"""Soil-sample import from CSV or GeoJSON, with errors per row and column.

Row numbering (CSV): ``row`` is the 1-based record number as a spreadsheet
shows it, the header being row 1, so the first data row is row 2. GeoJSON:
``row`` is the 0-based index into ``features`` (reported as "feature N").

An import that has any error returns the errors and no samples, unless
``skip_bad_rows`` is set, in which case the good rows are returned together
with the errors for the skipped ones. Header problems (a missing required
column) always reject the whole file. Samples farther than
``OUTSIDE_TOLERANCE_M`` outside the field boundary are set apart in
``outside`` (with their distance): a file from another field must not feed the
interpolation, so the caller stores them only when asked to.

Columns (case-insensitive, aliases in ``COLUMN_ALIASES``): ``sample_id``,
``lon``/``lat`` (WGS84) or ``x``/``y`` with an ``epsg`` code given by the
caller, ``depth_cm``, ``n_mg_kg`` (alkali-hydrolysable N, seed 001 sec. 1.2),
optional ``p_mg_kg``, ``k_mg_kg``, ``om_g_kg`` (organic matter), ``ph``.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import shapely

from fieldrx.geo.crs import (
    CrsError,
    crs_name,
    epsg_for_geometry,
    lonlat_to_utm_xy,
    to_utm,
    transform_xy,
)

COLUMN_ALIASES: dict[str, tuple[str, ...]] = {
    "sample_id": ("sample_id", "id", "sample", "name"),
    "lon": ("lon", "longitude", "lng", "long"),
    "lat": ("lat", "latitude"),
    "x": ("x", "easting", "east"),
    "y": ("y", "northing", "north"),
    "depth_cm": ("depth_cm", "depth"),
    # the seeds' soil-test names: alkali-hydrolysable N, available P (Olsen) and K
    "n_mg_kg": (
        "n_mg_kg",
        "n",
        "an_mg_kg",
        "alkali_n",
        "alkali_n_mg_kg",
        "alkali_hydrolysable_n",
        "avail_n",
    ),
    "p_mg_kg": ("p_mg_kg", "p", "ap_mg_kg", "avail_p", "available_p_mg_kg", "olsen_p_mg_kg"),
    "k_mg_kg": ("k_mg_kg", "k", "ak_mg_kg", "avail_k", "available_k_mg_kg"),
    "om_g_kg": ("om_g_kg", "om", "organic_matter"),
    "ph": ("ph",),
    "ndvi": ("ndvi",),
}
# (lowest, highest) accepted value of each numeric column
RANGES: dict[str, tuple[float, float]] = {
    "lon": (-180.0, 180.0),
    "lat": (-90.0, 90.0),
    "depth_cm": (0.0, 300.0),
    "n_mg_kg": (0.0, 10000.0),
    "p_mg_kg": (0.0, 10000.0),
    "k_mg_kg": (0.0, 100000.0),
    "om_g_kg": (0.0, 1000.0),
    "ph": (0.0, 14.0),
    "ndvi": (-1.0, 1.0),
}
OPTIONAL = ("p_mg_kg", "k_mg_kg", "om_g_kg", "ph", "ndvi")
VALUE_COLUMNS = ("n_mg_kg", "ndvi")
# Soil N as labs report it: alkali-hydrolysable N (seed 001 sec. 1.2, the nutrient-balance
# model's input), mineral N (Nmin: nitrate + ammonium) or total N (Kjeldahl / combustion).
N_FORMS = ("alkali_hydrolysable", "mineral", "total")  # what a rate model can be fed with
DEFAULT_DEPTH_CM = 20.0  # seed 001 samples 0-20 cm
# A sample this close outside the boundary is the field's own (handheld GNSS error and
# a boundary drawn on an orthophoto are each a few metres); farther, it is set apart.
OUTSIDE_TOLERANCE_M = 10.0


@dataclass
class SoilSample:
    """One sample, always in WGS84 lon/lat (``row`` is where it came from)."""

    row: int
    sample_id: str
    lon: float
    lat: float
    depth_cm: float
    n_mg_kg: float | None
    p_mg_kg: float | None = None
    k_mg_kg: float | None = None
    om_g_kg: float | None = None
    ph: float | None = None
    ndvi: float | None = None
    # which N the lab measured (``N_FORMS``); seed 001's model needs alkali-hydrolysable N
    n_form: str = "alkali_hydrolysable"

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class RowError:
    """A problem at one row (CSV record number, header = 1) or feature index, in one column."""

    row: int
    column: str | None
    message: str
    kind: str = "row"  # "row" (CSV) or "feature" (GeoJSON)

    def __str__(self) -> str:
        where = f"{self.kind} {self.row}"
        if self.column:
            where += f", column {self.column!r}"
        return f"{where}: {self.message}"

    def to_dict(self) -> dict[str, Any]:
        return {"row": self.row, "column": self.column, "message": self.message, "kind": self.kind}


@dataclass
class SoilImport:
    """Result of an import: samples (empty if rejected), errors, samples outside the field."""

    samples: list[SoilSample] = field(default_factory=list)
    errors: list[RowError] = field(default_factory=list)
    outside: list[SoilSample] = field(default_factory=list)  # also in samples
    rejected: bool = False  # True when errors made the import store nothing
    outside_distance_m: list[float] = field(default_factory=list)  # one per ``outside``

    def inside_samples(self) -> list[SoilSample]:
        """The samples within the field (or within the tolerance of its boundary)."""
        away = {id(s) for s in self.outside}
        return [s for s in self.samples if id(s) not in away]

    @property
    def ok(self) -> bool:
        return not self.errors

    def lonlat(self) -> np.ndarray:
        return np.array([[s.lon, s.lat] for s in self.samples], dtype=float).reshape(-1, 2)

    def values(self, column: str = "n_mg_kg") -> np.ndarray:
        return np.array(
            [np.nan if getattr(s, column) is None else getattr(s, column) for s in self.samples],
            dtype=float,
        )

    def summary(self) -> dict[str, Any]:
        distances: list[float | None] = [*self.outside_distance_m] or [None] * len(self.outside)
        return {
            "n_samples": len(self.samples),
            "n_errors": len(self.errors),
            "rejected": self.rejected,
            "errors": [e.to_dict() for e in self.errors],
            "outside": [
                {
                    "row": s.row,
                    "sample_id": s.sample_id,
                    "lon": s.lon,
                    "lat": s.lat,
                    "distance_m": None if d is None else round(d, 1),
                }
                for s, d in zip(
                    self.outside,
                    distances,
                    strict=True,
                )
            ],
            "outside_tolerance_m": OUTSIDE_TOLERANCE_M,
        }


class SoilFormatError(ValueError):
    """The file cannot be read at all (not CSV/GeoJSON, bad encoding, bad EPSG)."""


def _number(raw: Any, col: str, row: int, errs: list[RowError], kind: str) -> float | None:
    if raw is None or (isinstance(raw, str) and raw.strip() == ""):
        return None
    if isinstance(raw, bool):
        errs.append(RowError(row, col, f"expected a number, got {raw!r}", kind))
        return None
    try:
        v = float(raw.strip().replace(",", ".") if isinstance(raw, str) else raw)
    except (TypeError, ValueError):
        errs.append(RowError(row, col, f"expected a number, got {raw!r}", kind))
        return None
    if not math.isfinite(v):
        errs.append(RowError(row, col, f"value {raw!r} is not finite", kind))
        return None
    lo, hi = RANGES.get(col, (-math.inf, math.inf))
    if not lo <= v <= hi:
        errs.append(RowError(row, col, f"value {v:g} out of range [{lo:g}, {hi:g}]", kind))
        return None
    return v


def rows_to_samples(
    records: list[tuple[int, dict[str, Any]]],
    epsg: int | None,
    kind: str,
    geometry_xy: dict[int, tuple[float, float]] | None = None,
    value_column: str | None = "n_mg_kg",
) -> tuple[list[SoilSample], list[RowError]]:
    """Validate normalised records (canonical column -> raw text or number, in the units of
    the canonical names); ``geometry_xy`` (GeoJSON) overrides columns. ``value_column`` is
    the value every row must have (None: none is required, e.g. a P/K-only lab file)."""
    samples: list[SoilSample] = []
    errors: list[RowError] = []
    projected = epsg is not None and epsg != 4326
    xcol, ycol = ("x", "y") if projected else ("lon", "lat")
    seen: dict[str, int] = {}
    pending_xy: list[tuple[int, float, float]] = []
    for row, rec in records:
        errs: list[RowError] = []
        sid = rec.get("sample_id")
        sid = "" if sid is None else str(sid).strip()
        if not sid:
            sid = f"{kind}-{row}"
        elif sid in seen:
            errs.append(
                RowError(
                    row,
                    "sample_id",
                    f"duplicate sample id {sid!r} (first at {kind} {seen[sid]})",
                    kind,
                )
            )
        x: float | None
        y: float | None
        if geometry_xy is not None and row in geometry_xy:
            x, y = geometry_xy[row]
            if not projected:
                x = _number(x, "lon", row, errs, kind)
                y = _number(y, "lat", row, errs, kind)
        else:
            x = _number(rec.get(xcol), xcol, row, errs, kind)
            y = _number(rec.get(ycol), ycol, row, errs, kind)
            for c, v in ((xcol, x), (ycol, y)):
                if v is None and not any(e.column == c for e in errs):
                    errs.append(RowError(row, c, "missing value", kind))
        n = _number(rec.get("n_mg_kg"), "n_mg_kg", row, errs, kind)
        depth = _number(rec.get("depth_cm"), "depth_cm", row, errs, kind)
        opt: dict[str, Any] = {c: _number(rec.get(c), c, row, errs, kind) for c in OPTIONAL}
        required = n if value_column == "n_mg_kg" else opt.get(value_column or "")
        if (
            value_column is not None
            and required is None
            and not any(e.column == value_column for e in errs)
        ):
            errs.append(RowError(row, value_column, "missing value", kind))
        if errs:
            errors.extend(errs)
            continue
        assert x is not None and y is not None  # a missing one is a row error above
        seen[sid] = row
        samples.append(
            SoilSample(
                row=row,
                sample_id=sid,
                lon=float(x),  # replaced below when projected
                lat=float(y),
                depth_cm=DEFAULT_DEPTH_CM if depth is None else depth,
                n_mg_kg=n,
                **opt,
            )
        )
        pending_xy.append((len(samples) - 1, float(x), float(y)))
    if projected and samples:
        idx = np.array([p[0] for p in pending_xy])
        lon, lat = transform_xy(
            np.array([p[1] for p in pending_xy]),
            np.array([p[2] for p in pending_xy]),
            int(epsg or 4326),
            4326,
        )
        for i, lo, la in zip(idx, lon, lat, strict=True):
            s = samples[i]
            if not (math.isfinite(lo) and math.isfinite(la)):
                errors.append(RowError(s.row, "x", f"cannot transform from EPSG:{epsg}", kind))
            s.lon, s.lat = float(lo), float(la)
        samples = [s for s in samples if math.isfinite(s.lon) and math.isfinite(s.lat)]
    return samples, errors


def check_epsg(epsg: int | None) -> None:
    """``SoilFormatError`` naming the code when pyproj does not know it."""
    if epsg is None:
        return
    try:
        crs_name(int(epsg))
    except (CrsError, ValueError, TypeError) as exc:
        raise SoilFormatError(f"unknown EPSG code {epsg!r}") from exc


def finish_import(
    samples: list[SoilSample],
    errors: list[RowError],
    skip_bad_rows: bool,
    boundary_wgs84: Any,
    fatal: bool = False,
) -> SoilImport:
    if errors and (fatal or not skip_bad_rows):
        return SoilImport([], errors, [], rejected=True)
    outside: list[SoilSample] = []
    dist: list[float] = []
    if boundary_wgs84 is not None and samples:
        d = distance_outside_m(
            boundary_wgs84, np.array([[s.lon, s.lat] for s in samples], dtype=float)
        )
        away = d > OUTSIDE_TOLERANCE_M
        outside = [s for s, a in zip(samples, away, strict=True) if a]
        dist = [float(x) for x in d[away]]
    if not samples:
        if not errors:
            errors = [RowError(1, None, "no samples in the file")]
        return SoilImport([], errors, [], rejected=True)  # nothing usable to store
    return SoilImport(samples, errors, outside, rejected=False, outside_distance_m=dist)


def distance_outside_m(boundary_wgs84: Any, lonlat: np.ndarray) -> np.ndarray:
    """Distance in metres from each point to the field (0 inside or on the boundary).

    Measured in the field's UTM zone, so a sample 100 km away reads ~100000 m.
    """
    epsg = epsg_for_geometry(boundary_wgs84)
    poly = to_utm(boundary_wgs84, epsg)
    x, y = lonlat_to_utm_xy(lonlat[:, 0], lonlat[:, 1], epsg)
    return np.asarray(shapely.distance(poly, shapely.points(np.column_stack([x, y]))), float)


def _resolve_header(header: list[str]) -> tuple[dict[str, int], list[RowError]]:
    norm = [h.strip().lower().lstrip("\ufeff") for h in header]
    colmap: dict[str, int] = {}
    for canon, aliases in COLUMN_ALIASES.items():
        for a in aliases:
            if a in norm:
                colmap[canon] = norm.index(a)
                break
    return colmap, []


def _check_value_column(value_column: str) -> None:
    if value_column not in VALUE_COLUMNS:
        raise SoilFormatError(f"value_column must be one of {list(VALUE_COLUMNS)}")


def parse_soil_csv(
    data: bytes | str,
    epsg: int | None = None,
    skip_bad_rows: bool = False,
    boundary_wgs84: Any = None,
    value_column: str = "n_mg_kg",
) -> SoilImport:
    """Parse a CSV of samples. With ``epsg`` (not 4326) the x/y columns are used.

    ``value_column`` is the column every row must have (``n_mg_kg`` for soil
    samples, ``ndvi`` for crop-sensing points).

    Delimiter (comma, semicolon, tab) is sniffed. Errors name the row (header
    = row 1) and column; see the module docstring for the reject rule.
    """
    check_epsg(epsg)
    _check_value_column(value_column)
    if isinstance(data, bytes):
        try:
            text = data.decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise SoilFormatError(f"CSV is not UTF-8 text (byte {exc.start})") from exc
    else:
        text = data.lstrip("\ufeff")
    if not text.strip():
        raise SoilFormatError("CSV file is empty")
    first = text.splitlines()[0]
    delim = max([",", ";", "\t"], key=first.count)
    reader = csv.reader(io.StringIO(text), delimiter=delim)
    header = next(reader)
    colmap, errors = _resolve_header(header)
    projected = epsg is not None and epsg != 4326
    need = ["x", "y"] if projected else ["lon", "lat"]
    need.append(value_column)
    for c in need:
        if c not in colmap:
            hint = ""
            if c in ("lon", "lat") and "x" in colmap:
                hint = " (x/y columns found: pass the EPSG code of their coordinate system)"
            errors.append(
                RowError(
                    1, c, f"missing column (accepted names: {', '.join(COLUMN_ALIASES[c])}){hint}"
                )
            )
    if errors:
        return finish_import([], errors, skip_bad_rows, boundary_wgs84, fatal=True)
    records: list[tuple[int, dict[str, Any]]] = []
    for i, fields_ in enumerate(reader, start=2):
        if not any(f.strip() for f in fields_):
            continue  # blank line
        rec: dict[str, Any] = {}
        for canon, j in colmap.items():
            rec[canon] = fields_[j] if j < len(fields_) else None
        if len(fields_) > len(header):
            errors.append(
                RowError(i, None, f"{len(fields_)} fields but the header has {len(header)}")
            )
            continue
        records.append((i, rec))
    samples, errs = rows_to_samples(records, epsg, "row", value_column=value_column)
    errors.extend(errs)
    errors.sort(key=lambda e: e.row)
    return finish_import(samples, errors, skip_bad_rows, boundary_wgs84)


def parse_soil_geojson(
    data: bytes | str | dict[str, Any],
    epsg: int | None = None,
    skip_bad_rows: bool = False,
    boundary_wgs84: Any = None,
    value_column: str = "n_mg_kg",
) -> SoilImport:
    """Parse a GeoJSON FeatureCollection of Point features (properties as CSV columns).

    Coordinates are lon/lat (RFC 7946) unless ``epsg`` says otherwise. Errors
    name the feature index (0-based) and the property.
    """
    check_epsg(epsg)
    _check_value_column(value_column)
    try:
        obj = json.loads(data) if isinstance(data, bytes | str) else data
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise SoilFormatError(f"not valid JSON: {exc}") from exc
    if not isinstance(obj, dict) or obj.get("type") != "FeatureCollection":
        raise SoilFormatError("GeoJSON must be a FeatureCollection of Point features")
    feats = obj.get("features")
    if not isinstance(feats, list):
        raise SoilFormatError("GeoJSON FeatureCollection has no 'features' list")
    errors: list[RowError] = []
    records: list[tuple[int, dict[str, Any]]] = []
    geom_xy: dict[int, tuple[float, float]] = {}
    for i, f in enumerate(feats):
        if not isinstance(f, dict) or f.get("type") != "Feature":
            errors.append(RowError(i, None, "not a GeoJSON Feature", "feature"))
            continue
        g = f.get("geometry") or {}
        coords = g.get("coordinates") if isinstance(g, dict) else None
        if (
            not isinstance(g, dict)
            or g.get("type") != "Point"
            or not isinstance(coords, list)
            or len(coords) < 2
        ):
            errors.append(RowError(i, "geometry", "expected a Point geometry", "feature"))
            continue
        props = f.get("properties") or {}
        if not isinstance(props, dict):
            errors.append(RowError(i, "properties", "properties must be an object", "feature"))
            continue
        lower = {str(k).strip().lower(): v for k, v in props.items()}
        rec: dict[str, Any] = {}
        for canon, aliases in COLUMN_ALIASES.items():
            for a in aliases:
                if a in lower:
                    rec[canon] = lower[a]
                    break
        if "sample_id" not in rec and f.get("id") is not None:
            rec["sample_id"] = f["id"]
        try:
            geom_xy[i] = (float(coords[0]), float(coords[1]))
        except (TypeError, ValueError):
            errors.append(RowError(i, "geometry", f"bad coordinates {coords!r}", "feature"))
            continue
        records.append((i, rec))
    samples, errs = rows_to_samples(records, epsg, "feature", geom_xy, value_column)
    errors.extend(errs)
    errors.sort(key=lambda e: e.row)
    return finish_import(samples, errors, skip_bad_rows, boundary_wgs84)


def read_soil_samples(
    filename: str,
    data: bytes,
    epsg: int | None = None,
    skip_bad_rows: bool = False,
    boundary_wgs84: Any = None,
    value_column: str = "n_mg_kg",
) -> SoilImport:
    """Pick the parser from the file name (.csv/.txt or .geojson/.json)."""
    name = filename.lower()
    if name.endswith((".geojson", ".json")):
        return parse_soil_geojson(data, epsg, skip_bad_rows, boundary_wgs84, value_column)
    if name.endswith((".csv", ".txt", ".tsv")):
        return parse_soil_csv(data, epsg, skip_bad_rows, boundary_wgs84, value_column)
    raise SoilFormatError(f"unsupported soil file {filename!r} (expected .csv or .geojson)")
