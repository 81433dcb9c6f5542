"""ISO 11783-10 TASKDATA in: customers, farms, partfields, guidance lines and prescriptions.

``read_taskdata(files)`` takes the upload's files (a zip's members or the
TASKDATA files themselves, ``{path: bytes}``) and returns ``TaskDataSet``:
what FieldRx can create from it and what it skips, and why. Nothing here
touches the database (``services.imports`` stores, all or nothing).

Read (V3 and V4; one TASKDATA.XML or split into XFR external files):

* ``CTR``/``FRM``: customers and farms (a farm named "<customer> / <farm>"
  when it has a customer);
* ``PFD``: a field per partfield; its boundary is the union of the ``PLN``
  of type 1 (boundary), each ring from ``LSG`` type 1 (exterior) and type 2
  (interior = hole). Other ``PLN`` types (obstacles, water, buildings ...)
  are listed as skipped annotations: FieldRx has nowhere to keep them yet;
* ``GGP/GPN``: guidance patterns are listed with their line types and point
  count and skipped: FieldRx has no reference-line store (nor for partfield
  ``LSG``/``PNT`` such as sampling routes and entry points, also listed);
* ``TSK``: a prescription per task whose treatment zones carry a supported
  rate DDI: type-1 grids (one byte = zone code), type-2 grids (int32 per
  zone PDV, row 0 south, ISO 11783-10 Annex), or zone polygons. Rates are
  converted from the DDI's base unit with the ``isoxml`` package's DDI table:
  DDI 6 "Setpoint Mass Per Area Application Rate" mg/m^2 -> kg/ha (x 0.01).
  Volume (DDI 1, mm^3/m^2) and count rates would need a density FieldRx does
  not know: such tasks are skipped with that reason.

Every problem is a ``FormatError`` naming the file and element (for example
``TASKDATA.XML TSK[TSK1]/GRD: binary GRD00001.BIN has 396 bytes, H says
400``); a declared size above ``MAX_BINARY_BYTES`` is refused before reading.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
from isoxml.models.ddi_entities import DDEntity
from shapely.geometry import MultiPolygon, Polygon

from fieldrx.formats import FormatError
from fieldrx.formats.archive import parse_xml, read_zip, safe_member_name

MAX_BINARY_BYTES = 200 * 1024 * 1024
MAX_GRID_CELLS = 25_000_000
MASS_RATE_DDIS = {6: 0.01}  # DDI -> factor from base unit to kg/ha (mg/m^2 -> kg/ha)


@dataclass
class FarmIn:
    ref: str
    name: str


@dataclass
class FieldIn:
    ref: str
    name: str
    farm_ref: str | None
    boundary: Polygon | MultiPolygon
    declared_area_m2: float | None


@dataclass
class RxIn:
    """A prescription: ``rates_at(lon, lat)`` gives kg/ha at points (default outside)."""

    ref: str
    name: str
    field_ref: str
    product: str
    kind: str  # "grid type 1", "grid type 2", "zones"
    ddi: int
    unit: str
    default_rate_kg_ha: float
    zones: list[tuple[float, Any]] = field(default_factory=list)  # (rate, polygon) for "zones"
    grid: dict[str, Any] | None = None  # south, west, dlat, dlon, rates (rows x cols)

    def rates_at(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        out = np.full(len(lon), self.default_rate_kg_ha, dtype=float)
        if self.grid is not None:
            g = self.grid
            r = np.floor((lat - g["south"]) / g["dlat"]).astype(np.int64)
            c = np.floor((lon - g["west"]) / g["dlon"]).astype(np.int64)
            rows, cols = g["rates"].shape
            ok = (r >= 0) & (r < rows) & (c >= 0) & (c < cols)
            out[ok] = g["rates"][r[ok], c[ok]]
        else:
            if self.zones:
                tree = shapely.STRtree([poly for _, poly in self.zones])
                rates = np.asarray([rate for rate, _ in self.zones], dtype=float)
                pi, zi = tree.query(shapely.points(lon, lat), predicate="intersects")
                order = np.lexsort((zi, pi))  # a point on a shared edge: the first zone
                pi, zi = pi[order], zi[order]
                first = np.ones(len(pi), dtype=bool)
                first[1:] = pi[1:] != pi[:-1]
                out[pi[first]] = rates[zi[first]]
        return out

    def grid_centres(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """(lon, lat, rate) of every grid cell centre, or None for zone prescriptions."""
        if self.grid is None:
            return None
        g = self.grid
        rows, cols = g["rates"].shape
        lat = g["south"] + (np.arange(rows) + 0.5) * g["dlat"]
        lon = g["west"] + (np.arange(cols) + 0.5) * g["dlon"]
        lon2, lat2 = np.meshgrid(lon, lat)
        return lon2.ravel(), lat2.ravel(), g["rates"].ravel()


@dataclass
class TaskDataSet:
    version: str
    farms: list[FarmIn] = field(default_factory=list)
    fields: list[FieldIn] = field(default_factory=list)
    prescriptions: list[RxIn] = field(default_factory=list)
    skipped: list[dict[str, str]] = field(default_factory=list)

    def skip(self, what: str, why: str) -> None:
        self.skipped.append({"what": what, "why": why})


def _num(el: ET.Element, attr: str, where: str) -> float:
    v = el.get(attr)
    try:
        x = float(v)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise FormatError(f"{where}: attribute {attr}={v!r} is not a number") from None
    if not np.isfinite(x):
        raise FormatError(f"{where}: attribute {attr}={v!r} is not finite")
    return x


def _int(el: ET.Element, attr: str, where: str) -> int:
    x = _num(el, attr, where)
    if x != int(x):
        raise FormatError(f"{where}: attribute {attr}={el.get(attr)!r} is not an integer")
    return int(x)


def _ring(lsg: ET.Element, where: str) -> list[tuple[float, float]]:
    pts = []
    for k, p in enumerate(lsg.findall("PNT")):
        w = f"{where}/PNT[{k}]"
        lat, lon = _num(p, "C", w), _num(p, "D", w)
        if not (-90 <= lat <= 90 and -180 <= lon <= 180):
            raise FormatError(f"{w}: position {lat}, {lon} is not latitude/longitude")
        pts.append((lon, lat))
    return pts


def _polygon(pln: ET.Element, where: str) -> Polygon | None:
    shell = None
    holes = []
    for k, lsg in enumerate(pln.findall("LSG")):
        w = f"{where}/LSG[{k}]"
        pts = _ring(lsg, w)
        if len(pts) < 3:
            raise FormatError(f"{w}: a ring needs at least 3 points, got {len(pts)}")
        kind = lsg.get("A")
        if kind == "1":
            if shell is not None:
                raise FormatError(f"{w}: a PLN has one exterior ring (LSG A=1), found another")
            shell = pts
        elif kind == "2":
            holes.append(pts)
    if shell is None:
        raise FormatError(f"{where}: polygon without an exterior ring (LSG A=1)")
    return Polygon(shell, holes)


class _Files:
    """The upload's files by upper-case name relative to TASKDATA.XML's folder."""

    def __init__(self, files: dict[str, bytes]) -> None:
        clean = {safe_member_name(k): v for k, v in files.items()}
        tds = [k for k in clean if k.rsplit("/", 1)[-1].upper() == "TASKDATA.XML"]
        if not tds:
            names = ", ".join(sorted(clean)[:8]) or "nothing"
            raise FormatError(f"no TASKDATA.XML in the upload (found {names})")
        if len(tds) > 1:
            raise FormatError(f"more than one TASKDATA.XML in the upload: {sorted(tds)}")
        folder = tds[0][: -len("TASKDATA.XML")]
        self.by_name = {
            k[len(folder) :].upper(): v
            for k, v in clean.items()
            if k.startswith(folder) and "/" not in k[len(folder) :]
        }

    def get(self, name: str, where: str) -> bytes:
        data = self.by_name.get(name.upper())
        if data is None:
            raise FormatError(f"{where}: file {name} is missing from the upload")
        return data


def read_taskdata_zip(data: bytes) -> TaskDataSet:
    return read_taskdata(read_zip(data))


def read_taskdata(files: dict[str, bytes]) -> TaskDataSet:
    """See module docstring."""
    fs = _Files(files)
    root = parse_xml(fs.get("TASKDATA.XML", "upload"), "TASKDATA.XML")
    if root.tag != "ISO11783_TaskData":
        raise FormatError(f"TASKDATA.XML: root element is {root.tag}, not ISO11783_TaskData")
    major = root.get("VersionMajor")
    if major not in ("3", "4"):
        raise FormatError(f"TASKDATA.XML: VersionMajor={major!r} (only 3 and 4 are read)")
    source = {id(el): "TASKDATA.XML" for el in root}
    for k, xfr in enumerate(root.findall("XFR")):
        name = f"{xfr.get('A', '')}.XML"
        ext = parse_xml(fs.get(name, f"TASKDATA.XML XFR[{k}]"), name)
        if ext.tag != "XFC":
            raise FormatError(f"{name}: root element is {ext.tag}, not XFC")
        for el in list(ext):
            root.append(el)
            source[id(el)] = name
    ds = TaskDataSet(version=f"{major}.{root.get('VersionMinor', '0')}")

    def where(el: ET.Element, tag: str) -> str:
        return f"{source.get(id(el), 'TASKDATA.XML')} {tag}[{el.get('A', '?')}]"

    customers = {c.get("A"): (c.get("B") or "").strip() for c in root.findall("CTR")}
    for frm in root.findall("FRM"):
        name = (frm.get("B") or "").strip() or f"Farm {frm.get('A')}"
        ctr = customers.get(frm.get("I"))
        ds.farms.append(FarmIn(frm.get("A", ""), f"{ctr} / {name}" if ctr else name))
    for ref, name in customers.items():
        if not any(f.get("I") == ref for f in root.findall("FRM")):
            ds.skip(f"customer {name or ref}", "customer without a farm: fields keep no farm")
    products = {p.get("A"): (p.get("B") or "").strip() for p in root.findall("PDT")}
    for pfd in root.findall("PFD"):
        w = where(pfd, "PFD")
        polys: list[Polygon] = []
        for k, pln in enumerate(pfd.findall("PLN")):
            pw = f"{w}/PLN[{k}]"
            if pln.get("A") == "1":
                p = _polygon(pln, pw)
                if p is not None:
                    polys.append(p)
            else:
                ds.skip(
                    f"{w}/PLN[{k}] type {pln.get('A')} {pln.get('B') or ''}".strip(),
                    "obstacle/annotation polygons have no place in FieldRx yet",
                )
        for k, ggp in enumerate(pfd.findall("GGP")):
            for gpn in ggp.findall("GPN"):
                kinds = sorted({lsg.get("A", "?") for lsg in gpn.findall("LSG")})
                npts = sum(len(lsg.findall("PNT")) for lsg in gpn.findall("LSG"))
                ds.skip(
                    f"{w}/GGP[{k}] guidance pattern {gpn.get('B') or gpn.get('A')} "
                    f"(line types {','.join(kinds) or 'none'}, {npts} points)",
                    "FieldRx has no reference-line store",
                )
        for tag, label in (("LSG", "line"), ("PNT", "point")):
            for k, el in enumerate(pfd.findall(tag)):
                ds.skip(
                    f"{w}/{tag}[{k}] {label} type {el.get('A')} {el.get('B') or ''}".strip(),
                    "partfield lines and points (routes, flags, entries) have no place in "
                    "FieldRx yet",
                )
        if not polys:
            ds.skip(f"{w} {pfd.get('C') or ''}".strip(), "partfield without a boundary (PLN A=1)")
            continue
        geom: Polygon | MultiPolygon = polys[0] if len(polys) == 1 else MultiPolygon(polys)
        area = pfd.get("D")
        ds.fields.append(
            FieldIn(
                pfd.get("A", ""),
                (pfd.get("C") or "").strip() or f"Partfield {pfd.get('A')}",
                pfd.get("F"),
                geom,
                float(area) if area and area.isdigit() else None,
            )
        )
    field_refs = {f.ref for f in ds.fields}
    for tsk in root.findall("TSK"):
        _task(ds, tsk, where(tsk, "TSK"), fs, products, field_refs)
    return ds


def _ddi_unit(ddi: int) -> tuple[str, str]:
    try:
        d = DDEntity.from_id(ddi)
        return d.name, d.unit
    except KeyError:
        return f"unknown DDI {ddi}", ""


def _task(
    ds: TaskDataSet,
    tsk: ET.Element,
    w: str,
    fs: _Files,
    products: dict[str | None, str],
    field_refs: set[str],
) -> None:
    name = (tsk.get("B") or "").strip() or f"Task {tsk.get('A')}"
    tzns: dict[int, ET.Element] = {}
    for z in tsk.findall("TZN"):
        tzns[_int(z, "A", f"{w}/TZN")] = z
    if not tzns:
        ds.skip(f"{w} {name}", "task without treatment zones (no prescription)")
        return
    pfd = tsk.get("E")
    if pfd not in field_refs:
        ds.skip(f"{w} {name}", f"task's partfield {pfd!r} has no boundary in the upload")
        return
    # the rate DDI: the first PDV with a supported mass rate; name the others if none
    seen: list[str] = []
    ddi = None
    product = ""
    for z in tzns.values():
        for pdv in z.findall("PDV"):
            try:
                d = int(pdv.get("A", ""), 16)
            except ValueError:
                raise FormatError(f"{w}/TZN/PDV: DDI {pdv.get('A')!r} is not hex") from None
            if d in MASS_RATE_DDIS and ddi is None:
                ddi = d
                product = products.get(pdv.get("C"), "")
            seen.append(f"{d} ({_ddi_unit(d)[0]})")
    if ddi is None:
        ds.skip(
            f"{w} {name}",
            "no mass-per-area rate (DDI 6) among "
            + (", ".join(sorted(set(seen))) or "no process data")
            + ": volume and count rates need a density FieldRx does not have",
        )
        return
    factor = MASS_RATE_DDIS[ddi]

    def zone_rate(code: int, where: str) -> float:
        z = tzns.get(code)
        if z is None:
            return 0.0
        for pdv in z.findall("PDV"):
            if int(pdv.get("A", "0"), 16) == ddi:
                return _num(pdv, "B", f"{where}/TZN[{code}]/PDV") * factor
        return 0.0

    default_code = tsk.get("H")
    default = zone_rate(int(default_code), w) if default_code and default_code.isdigit() else 0.0
    rx = RxIn(
        ref=tsk.get("A", ""),
        name=name,
        field_ref=pfd or "",
        product=product,
        kind="zones",
        ddi=ddi,
        unit="kg/ha",
        default_rate_kg_ha=default,
    )
    grds = tsk.findall("GRD")
    if grds:
        rx.grid = _grid(grds[0], f"{w}/GRD", fs, tzns, ddi, factor, zone_rate)
        rx.kind = f"grid type {grds[0].get('I')}"
    else:
        for code, z in sorted(tzns.items()):
            polys = [
                _polygon(p, f"{w}/TZN[{code}]/PLN[{k}]") for k, p in enumerate(z.findall("PLN"))
            ]
            polys = [p for p in polys if p is not None]
            if polys:
                rx.zones.append((zone_rate(code, w), shapely.union_all(shapely.make_valid(polys))))
        if not rx.zones:
            ds.skip(f"{w} {name}", "treatment zones without polygons or grid")
            return
    ds.prescriptions.append(rx)


def _grid(
    grd: ET.Element,
    w: str,
    fs: _Files,
    tzns: dict[int, ET.Element],
    ddi: int,
    factor: float,
    zone_rate: Any,
) -> dict[str, Any]:
    south, west = _num(grd, "A", w), _num(grd, "B", w)
    dlat, dlon = _num(grd, "C", w), _num(grd, "D", w)
    cols, rows = _int(grd, "E", w), _int(grd, "F", w)
    if not (0 < dlat <= 1 and 0 < dlon <= 1):
        raise FormatError(f"{w}: cell size {dlat} x {dlon} degrees is not in (0, 1]")
    if cols < 1 or rows < 1 or rows * cols > MAX_GRID_CELLS:
        raise FormatError(f"{w}: {rows} x {cols} cells (1..{MAX_GRID_CELLS} accepted)")
    kind = grd.get("I")
    fname = f"{grd.get('G', '')}.BIN"
    declared = grd.get("H")
    if declared is not None:
        size = _int(grd, "H", w)
        if size > MAX_BINARY_BYTES:
            raise FormatError(
                f"{w}: binary {fname} declared as {size} bytes (> {MAX_BINARY_BYTES}): refused"
            )
    data = fs.get(fname, w)
    if kind == "1":
        want = rows * cols
        if len(data) != want or (declared is not None and int(declared) != len(data)):
            raise FormatError(
                f"{w}: binary {fname} has {len(data)} bytes, {rows} x {cols} type-1 cells "
                f"need {want} (H says {declared})"
            )
        codes = np.frombuffer(data, dtype=np.uint8).reshape(rows, cols)
        lut = np.asarray([zone_rate(c, w) for c in range(256)])
        rates = lut[codes]
    elif kind == "2":
        code = _int(grd, "J", w)
        z = tzns.get(code)
        if z is None:
            raise FormatError(f"{w}: grid zone J={code} is not a TZN of the task")
        pdvs = [int(p.get("A", "0"), 16) for p in z.findall("PDV")]
        if ddi not in pdvs:
            raise FormatError(f"{w}: TZN[{code}] has no PDV with DDI {ddi}")
        k = len(pdvs)
        want = rows * cols * 4 * k
        if len(data) != want or (declared is not None and int(declared) != len(data)):
            raise FormatError(
                f"{w}: binary {fname} has {len(data)} bytes, {rows} x {cols} cells x {k} "
                f"values x 4 need {want} (H says {declared})"
            )
        vals = np.frombuffer(data, dtype="<i4").reshape(rows, cols, k)[:, :, pdvs.index(ddi)]
        rates = vals.astype(float) * factor
    else:
        raise FormatError(f"{w}: grid type I={kind!r} (1 and 2 are defined)")
    return {"south": south, "west": west, "dlat": dlat, "dlon": dlon, "rates": rates}
