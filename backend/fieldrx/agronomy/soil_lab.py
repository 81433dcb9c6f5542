"""A soil lab's table -> soil samples, through a column mapping the user confirms.

German labs (LUFA, AGROLAB, Eurofins) export ``;``-separated CSV with decimal commas, often
in Windows-1252, with headers such as ``Probe; Rechtswert; Hochwert; Tiefe (cm); Nmin
(kg/ha); P2O5 (mg/100g); K2O (mg/100g); Humus (%); pH``. This module

1. reads the table (``read_table``: delimiter, encoding, decimal comma) without judging it,
2. proposes a mapping (``suggest_mapping``: which column is which quantity and in which
   unit, recognised from the header text and its unit in brackets),
3. applies a mapping (``apply_mapping``): every value is converted to the unit FieldRx
   stores (``TARGETS``) and handed to ``agronomy.soil.rows_to_samples``, which checks
   ranges and coordinates like any other soil import.

Unit conversions (each documented where it is defined in ``UNITS``):

* mass fractions: 1 % = 10 g/kg = 10,000 mg/kg; 1 mg/100 g = 10 mg/kg; ppm = mg/kg;
* oxides to elements (German labs report the CAL/DL extract as P2O5 and K2O): P =
  P2O5 x 2 M(P) / M(P2O5) = 0.4364, K = K2O x 2 M(K) / M(K2O) = 0.8301 (IUPAC masses);
* Nmin in kg N/ha -> mg N/kg of soil: the layer holds ``depth_cm x 0.01 m x 10,000 m2 x
  rho_b`` kg of soil per hectare, so mg/kg = kg/ha x 10 / (depth_cm x rho_b[g/cm3])
  (VDLUFA Methodenbuch I, A 6.1.4.1; rho_b defaults to 1.5 g/cm3, a loam's, and the depth
  is the row's sampling depth or the default 30 cm of an Nmin sample);
* soil organic carbon (Corg) -> organic matter ("Humus"): x 1.724 (van Bemmelen factor,
  the one VDLUFA uses).

Nothing here touches the database or decides what to store: see ``services.soil``.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
import unicodedata
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely

from fieldrx.agronomy.soil import (
    N_FORMS,
    RowError,
    SoilFormatError,
    SoilImport,
    check_epsg,
    finish_import,
    rows_to_samples,
)
from fieldrx.geo.crs import etrs89_utm_epsg_for, guess_epsg, to_utm

# What a column can be: target -> (canonical column of agronomy.soil, stored unit, label).
TARGETS: dict[str, tuple[str, str, str]] = {
    "sample_id": ("sample_id", "", "Sample id"),
    "x": ("x", "", "Easting / longitude"),
    "y": ("y", "", "Northing / latitude"),
    "depth": ("depth_cm", "cm", "Sampling depth"),
    "n": ("n_mg_kg", "mg/kg", "Nitrogen (N)"),
    "p": ("p_mg_kg", "mg/kg", "Phosphorus (P)"),
    "k": ("k_mg_kg", "mg/kg", "Potassium (K)"),
    "om": ("om_g_kg", "g/kg", "Organic matter (humus)"),
    "ph": ("ph", "", "pH"),
}
NUTRIENTS = ("n", "p", "k", "om", "ph")

P_PER_P2O5 = 2 * 30.973762 / (2 * 30.973762 + 5 * 15.999)  # 0.4364
K_PER_K2O = 2 * 39.0983 / (2 * 39.0983 + 15.999)  # 0.8301
OM_PER_CORG = 1.724  # van Bemmelen
DEFAULT_BULK_DENSITY_G_CM3 = 1.5
DEFAULT_NMIN_DEPTH_CM = 30.0  # an Nmin sample is 0-30 cm (then 30-60, 60-90)
KG_HA = "kg/ha"

_MASS = {"mg/kg": 1.0, "ppm": 1.0, "mg/100g": 10.0, "g/kg": 1000.0, "%": 10000.0}
# target -> unit -> factor to the stored unit (KG_HA is not a factor: see nmin_to_mg_kg)
UNITS: dict[str, dict[str, float]] = {
    "n": {**_MASS, KG_HA: math.nan},
    "p": {
        **_MASS,
        "P2O5 mg/100g": 10.0 * P_PER_P2O5,
        "P2O5 mg/kg": P_PER_P2O5,
    },
    "k": {
        **_MASS,
        "K2O mg/100g": 10.0 * K_PER_K2O,
        "K2O mg/kg": K_PER_K2O,
    },
    "om": {"g/kg": 1.0, "%": 10.0, "Corg %": 10.0 * OM_PER_CORG, "Corg g/kg": OM_PER_CORG},
    "depth": {"cm": 1.0, "m": 100.0, "mm": 0.1, "dm": 10.0},
    "ph": {"": 1.0},
    "x": {"": 1.0},
    "y": {"": 1.0},
    "sample_id": {"": 1.0},
}
DEFAULT_UNIT = {t: next(iter(u)) for t, u in UNITS.items()}


def nmin_to_mg_kg(kg_ha: float, depth_cm: float, bulk_density_g_cm3: float) -> float:
    """Nmin kg N/ha in a layer of ``depth_cm`` -> mg N per kg of soil (module docstring)."""
    return kg_ha * 10.0 / (depth_cm * bulk_density_g_cm3)


def _fold(text: str) -> str:
    """Lower case, umlauts spelled out, accents dropped: 'Länge' -> 'laenge'."""
    t = text.strip().lstrip("\ufeff").lower()
    for a, b in (("ä", "ae"), ("ö", "oe"), ("ü", "ue"), ("ß", "ss")):
        t = t.replace(a, b)
    return "".join(c for c in unicodedata.normalize("NFKD", t) if not unicodedata.combining(c))


# Header words (folded, the unit in brackets removed) -> target. English, German, lab codes.
HEADER_WORDS: dict[str, tuple[str, ...]] = {
    "sample_id": (
        "sample_id",
        "id",
        "sample",
        "name",
        "probe",
        "probe nr",
        "probe-nr",
        "probe-nr.",
        "probennr",
        "probennummer",
        "proben-nr",
        "proben-nr.",
        "probenbezeichnung",
        "nr",
        "nr.",
        "labornummer",
        "lab-nr",
        "punkt",
        "punkt-nr",
    ),
    "x": (
        "x",
        "lon",
        "lng",
        "long",
        "longitude",
        "easting",
        "east",
        "rechtswert",
        "rw",
        "ostwert",
        "laenge",
        "geogr. laenge",
        "e",
    ),
    "y": (
        "y",
        "lat",
        "latitude",
        "northing",
        "north",
        "hochwert",
        "hw",
        "nordwert",
        "breite",
        "geogr. breite",
        "n_coord",
    ),
    "depth": ("depth", "depth_cm", "tiefe", "entnahmetiefe", "probentiefe", "schicht", "horizont"),
    "n": (
        "n",
        "n_mg_kg",
        "nmin",
        "n-min",
        "n min",
        "nitrogen",
        "stickstoff",
        "n gesamt",
        "nt",
        "avail_n",
        "alkali_n",
        "alkali_n_mg_kg",
        "alkali-hydrolysable n",
        "alkali_hydrolysable_n",
        "an_mg_kg",
        "mineral_n",
        "mineral n",
        "total_n",
        "total n",
        "n_total",
    ),
    "p": (
        "p",
        "p_mg_kg",
        "ap_mg_kg",
        "avail_p",
        "available_p_mg_kg",
        "olsen_p_mg_kg",
        "p2o5",
        "phosphor",
        "phosphat",
        "p-cal",
        "p cal",
        "p2o5-cal",
        "p (cal)",
    ),
    "k": (
        "k",
        "k_mg_kg",
        "ak_mg_kg",
        "avail_k",
        "available_k_mg_kg",
        "k2o",
        "kalium",
        "k-cal",
        "k cal",
        "k2o-cal",
        "k (cal)",
    ),
    "om": ("om", "om_g_kg", "organic_matter", "organic matter", "humus", "corg", "c-org", "toc"),
    "ph": ("ph", "ph-wert", "ph wert", "ph (cacl2)", "ph-cacl2", "bodenreaktion"),
}
_UNIT_RE = re.compile(r"[\(\[]\s*([^\)\]]*?)\s*[\)\]]")


def _unit_text(header: str) -> str:
    m = _UNIT_RE.search(header)
    return _fold(m.group(1)).replace(" ", "") if m else ""


def _header_word(header: str) -> str:
    return re.sub(r"\s+", " ", _UNIT_RE.sub("", _fold(header))).strip(" :")


def suggest_unit(target: str, header: str) -> str:
    """The unit a header names (``N (kg/ha)``, ``P2O5 (mg/100g)``, ``Humus (%)``), else the
    target's usual one (``Nmin`` alone is kg/ha: that is how Nmin is reported)."""
    word, unit = _header_word(header), _unit_text(header)
    unit = {
        "mg/100": "mg/100g",
        "mg/100gboden": "mg/100g",
        "mg/kgboden": "mg/kg",
        "kgn/ha": KG_HA,
        "kg/ha": KG_HA,
        "gew.-%": "%",
        "masse-%": "%",
    }.get(unit, unit)
    if target == "p" and "p2o5" in word:
        return "P2O5 mg/kg" if unit in ("mg/kg", "ppm") else "P2O5 mg/100g"
    if target == "k" and "k2o" in word:
        return "K2O mg/kg" if unit in ("mg/kg", "ppm") else "K2O mg/100g"
    if target == "om" and word in ("corg", "c-org", "toc"):
        return "Corg g/kg" if unit == "g/kg" else "Corg %"
    if target == "n" and not unit and "min" in word:
        return KG_HA
    if unit in UNITS.get(target, {}):
        return unit
    if target == "om" and not unit and word == "humus":
        return "%"
    return DEFAULT_UNIT[target]


def suggest_n_form(header: str) -> str:
    """Which N a column holds, from its header: Nmin / mineral / nitrate -> mineral,
    total / gesamt / Nt -> total, else alkali-hydrolysable (the seed's ``alkali_n_mg_kg``)."""
    w = _header_word(header).replace("_", " ").replace("-", " ")
    words = set(w.split())
    if "min" in words or "nmin" in words or "mineral" in words or "no3" in w:
        return "mineral"
    if {"total", "gesamt", "nt"} & words:
        return "total"
    return "alkali_hydrolysable"


@dataclass
class Mapping:
    """Which column (header text) feeds which target, in which unit; the coordinate system
    of x/y; the bulk density for Nmin kg/ha; which N form the N column holds (``N_FORMS``).
    ``columns`` holds only mapped targets."""

    columns: dict[str, str]
    units: dict[str, str] = field(default_factory=dict)
    epsg: int | None = None
    bulk_density_g_cm3: float = DEFAULT_BULK_DENSITY_G_CM3
    n_form: str = "alkali_hydrolysable"

    def unit(self, target: str) -> str:
        return self.units.get(target) or DEFAULT_UNIT[target]


@dataclass
class Table:
    """A lab file as text cells: header, data rows (CSV: 1-based record number, header = 1;
    GeoJSON: 0-based feature index, ``kind`` "feature")."""

    header: list[str]
    rows: list[tuple[int, list[str]]]
    delimiter: str
    encoding: str
    decimal_comma: bool
    kind: str = "row"

    def column(self, name: str) -> list[str]:
        j = self.header.index(name)
        return [r[j] if j < len(r) else "" for _, r in self.rows]


def _decode(data: bytes) -> tuple[str, str]:
    try:
        return data.decode("utf-8-sig"), "utf-8"
    except UnicodeDecodeError:
        return data.decode("cp1252", errors="replace"), "windows-1252"


def read_table(filename: str, data: bytes) -> Table:
    """CSV/TXT text of a lab: delimiter sniffed from the header line (``;`` ``,`` tab), UTF-8
    or Windows-1252 (what Excel writes in Germany), blank lines and ``#`` comments skipped."""
    name = filename.lower()
    if name.endswith((".geojson", ".json")):
        return _geojson_table(filename, data)
    if name.endswith((".xlsx", ".xls", ".ods")):
        raise SoilFormatError(
            f"{filename!r}: spreadsheets are not read; save the sheet as CSV (Excel: 'CSV UTF-8' "
            "or 'CSV (Trennzeichen-getrennt)') and upload that"
        )
    if not name.endswith((".csv", ".txt", ".tsv")):
        raise SoilFormatError(
            f"unsupported lab file {filename!r} (expected .csv, .txt or .geojson)"
        )
    text, encoding = _decode(data)
    lines = [ln for ln in text.splitlines()]
    start = next((i for i, ln in enumerate(lines) if ln.strip() and not ln.startswith("#")), None)
    if start is None:
        raise SoilFormatError(f"{filename!r} is empty")
    delim = max([";", ",", "\t"], key=lines[start].count)
    reader = csv.reader(io.StringIO("\n".join(lines[start:])), delimiter=delim)
    header = [h.strip().lstrip("\ufeff") for h in next(reader)]
    if len([h for h in header if h]) < 2:
        raise SoilFormatError(f"{filename!r}: the first line has fewer than two column names")
    dup = sorted({h for h in header if h and header.count(h) > 1})
    if dup:
        raise SoilFormatError(f"{filename!r}: column names used twice: {', '.join(dup)}")
    rows = [
        (i, [c.strip() for c in r])
        for i, r in enumerate(reader, start=start + 2)
        if any(c.strip() for c in r)
    ]
    cells = [c for _, r in rows[:200] for c in r]
    comma = delim != "," and sum(bool(re.fullmatch(r"-?\d+,\d+", c)) for c in cells) > sum(
        bool(re.fullmatch(r"-?\d+\.\d+", c)) for c in cells
    )
    return Table(header, rows, delim, encoding, comma)


def _geojson_table(filename: str, data: bytes) -> Table:
    """A FeatureCollection of Points as a table: ``lon``/``lat`` from the geometry (RFC 7946),
    then every property; a feature that is not a Point gets empty coordinates (rejected
    with its index like any row without them)."""
    try:
        obj = json.loads(data)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise SoilFormatError(f"{filename!r} is not valid JSON: {exc}") from exc
    feats = obj.get("features") if isinstance(obj, dict) else None
    if not isinstance(feats, list):
        raise SoilFormatError(f"{filename!r}: expected a GeoJSON FeatureCollection of Points")
    keys: dict[str, None] = {}
    for f in feats:
        props = f.get("properties") if isinstance(f, dict) else None
        for k in props if isinstance(props, dict) else {}:
            keys.setdefault(str(k), None)
    header = ["lon", "lat", *(k for k in keys if k not in ("lon", "lat"))]
    rows = []
    for i, f in enumerate(feats):
        f = f if isinstance(f, dict) else {}
        g = f.get("geometry")
        g = g if isinstance(g, dict) else {}
        c = g.get("coordinates") if g.get("type") == "Point" else None
        xy = [str(c[0]), str(c[1])] if isinstance(c, list) and len(c) >= 2 else ["", ""]
        props = f.get("properties")
        props = props if isinstance(props, dict) else {}
        rows.append((i, xy + ["" if props.get(k) is None else str(props[k]) for k in header[2:]]))
    return Table(header, rows, "", "utf-8", False, kind="feature")


def parse_number(raw: str, decimal_comma: bool) -> float:
    """'12,5' (decimal comma) or '12.5'; '1.234,5' with decimal comma is 1234.5; a cell with
    a '<' (below the detection limit) or text raises ValueError with the reason."""
    t = raw.strip().replace("\u2212", "-").replace(" ", "")
    if t.startswith(("<", ">")):
        raise ValueError(f"{raw!r} is a detection limit, not a value")
    if decimal_comma:
        t = t.replace(".", "").replace(",", ".")
    elif "," in t and "." not in t:
        t = t.replace(",", ".")
    v = float(t)
    if not math.isfinite(v):
        raise ValueError(f"{raw!r} is not finite")
    return v


def parse_depth(raw: str, decimal_comma: bool) -> float:
    """'30', '0-30', '0 - 30' (a layer: its lower bound is the sampling depth)."""
    m = re.fullmatch(r"\s*(\d+(?:[.,]\d+)?)\s*[-–/]\s*(\d+(?:[.,]\d+)?)\s*", raw)
    if m:
        return parse_number(m.group(2), decimal_comma)
    return parse_number(raw, decimal_comma)


def suggest_mapping(table: Table, near_lonlat: tuple[float, float]) -> Mapping:
    """Target -> column from the header words (first match wins, each column used once),
    units from the headers, CRS from the magnitudes of the x/y columns."""
    cols: dict[str, str] = {}
    used: set[str] = set()
    words = {h: _header_word(h) for h in table.header if h}
    for target, aliases in HEADER_WORDS.items():
        for h, w in words.items():
            if h not in used and (w in aliases or w.replace("_", " ") in aliases):
                cols[target] = h
                used.add(h)
                break
    units = {t: suggest_unit(t, h) for t, h in cols.items() if t in UNITS and len(UNITS[t]) > 1}
    epsg = None
    if "x" in cols and "y" in cols:
        x = _floats(table.column(cols["x"]), table.decimal_comma)
        y = _floats(table.column(cols["y"]), table.decimal_comma)
        epsg = guess_epsg(x, y, *near_lonlat)
    n_form = suggest_n_form(cols["n"]) if "n" in cols else "alkali_hydrolysable"
    if units.get("n") == KG_HA:
        n_form = "mineral"  # kg N/ha is how Nmin is reported
    return Mapping(cols, units, epsg, n_form=n_form)


def _floats(cells: list[str], decimal_comma: bool) -> np.ndarray:
    out = []
    for c in cells[:500]:
        try:
            out.append(parse_number(c, decimal_comma))
        except ValueError:
            out.append(math.nan)
    return np.array(out, float)


HEADER = "header"  # RowError.kind of a mapping problem (not a data row)


def check_mapping(table: Table, m: Mapping) -> list[RowError]:
    """Errors of the mapping itself (kind ``header``): unknown columns or
    units, a column used twice, no coordinates, no nutrient, no coordinate system."""
    errs: list[RowError] = []
    for t, col in m.columns.items():
        if t not in TARGETS:
            errs.append(
                RowError(1, col, f"unknown target {t!r} (one of {', '.join(TARGETS)})", HEADER)
            )
        elif col not in table.header:
            errs.append(RowError(1, col, f"the file has no column {col!r} (mapped to {t})", HEADER))
    for col in {c for c in m.columns.values() if list(m.columns.values()).count(c) > 1}:
        errs.append(RowError(1, col, "column mapped to more than one quantity", HEADER))
    for t, u in m.units.items():
        if t in UNITS and u not in UNITS[t]:
            msg = f"unit {u!r} of {t}: one of {list(UNITS[t])}"
            errs.append(RowError(1, m.columns.get(t), msg, HEADER))
    for t in ("x", "y"):
        if t not in m.columns:
            errs.append(
                RowError(1, None, f"no column mapped to {t} ({TARGETS[t][2].lower()})", HEADER)
            )
    if not any(t in m.columns for t in NUTRIENTS):
        errs.append(
            RowError(1, None, "no column mapped to a nutrient (N, P, K, humus or pH)", HEADER)
        )
    if m.epsg is None:
        errs.append(RowError(1, None, "no coordinate system chosen for x/y", HEADER))
    if not 0.5 <= m.bulk_density_g_cm3 <= 2.5:
        errs.append(RowError(1, None, "bulk density must be 0.5-2.5 g/cm3", HEADER))
    return errs


def _mapped_row(
    table: Table,
    m: Mapping,
    idx: dict[str, int],
    row: int,
    cells: list[str],
    errors: list[RowError],
) -> dict[str, Any] | None:
    """One row's values under the mapping, in the canonical units; None (its errors added
    to ``errors``) when a cell is not a number."""
    rec: dict[str, Any] = {}
    bad = False
    for t, j in idx.items():
        raw = cells[j] if j < len(cells) else ""
        canon = TARGETS[t][0]
        if t == "sample_id" or not raw:
            rec[canon] = raw or None
            continue
        try:
            v = (parse_depth if t == "depth" else parse_number)(raw, table.decimal_comma)
        except ValueError as exc:
            msg = str(exc) if "limit" in str(exc) else f"expected a number, got {raw!r}"
            errors.append(RowError(row, m.columns[t], msg, table.kind))
            bad = True
            continue
        f = UNITS[t][m.unit(t)]
        rec[canon] = v if math.isnan(f) else v * f
    return None if bad else rec


def apply_mapping(table: Table, m: Mapping, boundary_wgs84: Any) -> SoilImport:
    """Samples of every good row (``rejected`` False) plus the errors of the bad ones, or, when
    the mapping itself is wrong, no samples and those errors (``rejected`` True). Errors name
    the file's column (the quantity it was mapped to in brackets)."""
    errs = check_mapping(table, m)
    if m.n_form not in N_FORMS:
        errs.append(
            RowError(1, None, f"n_form must be one of {list(N_FORMS)}, got {m.n_form!r}", HEADER)
        )
    if errs:
        return SoilImport([], errs, [], rejected=True)
    check_epsg(m.epsg)
    idx = {t: table.header.index(c) for t, c in m.columns.items()}
    records: list[tuple[int, dict[str, Any]]] = []
    errors: list[RowError] = []
    nmin = m.unit("n") == KG_HA and "n" in idx
    kind = table.kind
    for row, cells in table.rows:
        if len(cells) > len(table.header):
            errors.append(
                RowError(
                    row, None, f"{len(cells)} fields but the header has {len(table.header)}", kind
                )
            )
            continue
        rec = _mapped_row(table, m, idx, row, cells, errors)
        if rec is None:
            continue
        if nmin and rec.get("n_mg_kg") is not None:
            depth = rec.get("depth_cm") or DEFAULT_NMIN_DEPTH_CM
            rec["depth_cm"] = depth
            rec["n_mg_kg"] = nmin_to_mg_kg(rec["n_mg_kg"], depth, m.bulk_density_g_cm3)
        if m.epsg == 4326:
            rec["lon"], rec["lat"] = rec.pop("x", None), rec.pop("y", None)
        records.append((row, rec))
    samples, more = rows_to_samples(records, m.epsg, kind, value_column=None)
    for smp in samples:
        smp.n_form = m.n_form
    back = {TARGETS[t][0]: c for t, c in m.columns.items()} | (
        {"lon": m.columns.get("x"), "lat": m.columns.get("y")} if m.epsg == 4326 else {}
    )
    for e in more:
        if e.column in back:
            e.message = f"{e.message} ({e.column})"
            e.column = back[e.column]
    errors.extend(more)
    errors.sort(key=lambda e: e.row)
    if not samples:
        if not errors:
            errors = [RowError(1, None, "no samples in the file", HEADER)]
        return SoilImport([], errors, [], rejected=True)
    return finish_import(samples, errors, True, boundary_wgs84)


EXAMPLE_HEADER = (
    "Probe",
    "Rechtswert",
    "Hochwert",
    "Tiefe (cm)",
    "Nmin (kg/ha)",
    "P2O5 (mg/100g)",
    "K2O (mg/100g)",
    "Humus (%)",
    "pH",
)


def example_lab_csv(boundary_wgs84: Any, n: int = 3) -> tuple[str, int]:
    """An example lab file for a field, as a German lab writes it (``;``, decimal commas,
    ETRS89/UTM coordinates): an ``n`` x ``n`` grid of points inside the field. Returns the
    text and the EPSG code of its coordinates."""
    c = boundary_wgs84.representative_point()
    epsg = etrs89_utm_epsg_for(c.x, c.y)
    poly = to_utm(boundary_wgs84, epsg)
    x0, y0, x1, y1 = poly.bounds
    pts = [
        shapely.Point(x0 + (x1 - x0) * (i + 0.5) / n, y0 + (y1 - y0) * (j + 0.5) / n)
        for j in range(n)
        for i in range(n)
    ]
    pts = [p for p in pts if poly.contains(p)] or [poly.representative_point()]
    lines = [";".join(EXAMPLE_HEADER)]
    for k, p in enumerate(pts, start=1):
        vals = (
            f"P{k:02d}",
            f"{p.x:.1f}",
            f"{p.y:.1f}",
            "0-30",
            f"{40 + 3 * k:.0f}",
            f"{12 + 0.5 * k:.1f}",
            f"{15 + 0.7 * k:.1f}",
            f"{2.1 + 0.1 * k:.1f}",
            f"{6.2 + 0.05 * k:.2f}",
        )
        lines.append(";".join(v.replace(".", ",") for v in vals))
    return "\n".join(lines) + "\n", epsg
