"""ISO 11783-10 TASKDATA in: customers, farms, partfields, guidance lines and prescriptions.

``read_taskdata(files)`` takes the upload's files (a zip's members or the
TASKDATA files themselves, ``{path: bytes}``) and returns ``TaskDataSet``:
what FieldRx can create from it and what it skips, and why. Nothing here
touches the database (``services.imports`` stores, all or nothing).

Read (V3 and V4; one TASKDATA.XML or split into XFR external files):

* ``CTR``/``FRM``: customers and farms (a farm named "<customer> / <farm>"
  when it has a customer);
* ``PFD``: a field per partfield (``isoxml_partfield``); its boundary is the union of the ``PLN``
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
``TASKDATA.XML TSK[TSK1]/GRD: binary GRD00001.BIN has 396 bytes, ... need
400``); a declared size above ``MAX_BINARY_BYTES`` is refused before reading, a
declared size (H) that differs from a binary matching the grid is noted.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
from isoxml.models.ddi_entities import DDEntity

from fieldrx.formats import FormatError
from fieldrx.formats.archive import parse_xml, read_zip, safe_member_name
from fieldrx.formats.isoxml_partfield import (
    FieldIn,
    attr_int,
    attr_num,
    pln_polygon,
    read_partfield,
)

MAX_BINARY_BYTES = 200 * 1024 * 1024
MAX_GRID_CELLS = 25_000_000
MASS_RATE_DDIS = {6: 0.01}  # DDI -> factor from base unit to kg/ha (mg/m^2 -> kg/ha)
VOLUME_RATE_DDIS = {1: 0.01}  # DDI -> factor from base unit to l/ha (mm^3/m^2 -> l/ha)


@dataclass
class FarmIn:
    ref: str
    name: str


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
    density_kg_l: float | None = None  # a volume rate's density (l/ha x kg/l -> kg/ha)
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

    def coverage(self) -> Any:
        """Where the prescription has data (lon/lat): the grid's rectangle or the zones."""
        if self.grid is not None:
            g = self.grid
            rows, cols = g["rates"].shape
            return shapely.box(
                g["west"], g["south"], g["west"] + cols * g["dlon"], g["south"] + rows * g["dlat"]
            )
        return shapely.union_all([poly for _, poly in self.zones])

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
    skipped: list[dict[str, Any]] = field(default_factory=list)
    # TSK/TLG: TimeLogs inside the set (header + binary names; read by the TimeLog import)
    timelogs: list[dict[str, Any]] = field(default_factory=list)

    def skip(self, what: str, why: str, bad: bool = False, needs_density: bool = False) -> None:
        self.skipped.append({"what": what, "why": why, "bad": bad, "needs_density": needs_density})


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


def read_taskdata(files: dict[str, bytes], density_kg_l: float | None = None) -> TaskDataSet:
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
    bad: list[str] = []
    for pfd in root.findall("PFD"):
        w = where(pfd, "PFD")
        label = f"{w} {pfd.get('C') or ''}".strip()
        try:
            fin = read_partfield(pfd, w)
        except FormatError as exc:
            # one broken partfield does not sink the others: it is named in the preview
            # and the confirmed import stores the rest
            ds.skip(label, f"refused: {exc}", bad=True)
            bad.append(str(exc))
            continue
        if fin is None:
            ds.skip(label, "partfield without a boundary (PLN A=1)")
            continue
        ds.fields.append(fin)
    if bad and not ds.fields:
        raise FormatError("; ".join(bad))
    ctx = _TaskCtx(fs, products, {f.ref for f in ds.fields}, density_kg_l)
    for tsk in root.findall("TSK"):
        _task(ds, tsk, where(tsk, "TSK"), ctx)
    return ds


def _ddi_unit(ddi: int) -> tuple[str, str]:
    try:
        d = DDEntity.from_id(ddi)
        return d.name, d.unit
    except KeyError:
        return f"unknown DDI {ddi}", ""


@dataclass
class _TaskCtx:
    """What a task's reading needs from the set around it."""

    fs: _Files
    products: dict[str | None, str]
    field_refs: set[str]
    density_kg_l: float | None


def _rate_ddi(
    tzns: dict[int, ET.Element], w: str, products: dict[str | None, str]
) -> tuple[int | None, str, list[str]]:
    """The task's rate DDI (mass first, then volume), its product and every DDI seen."""
    seen: list[str] = []
    found: dict[int, str] = {}
    for z in tzns.values():
        for pdv in z.findall("PDV"):
            try:
                d = int(pdv.get("A", ""), 16)
            except ValueError:
                raise FormatError(f"{w}/TZN/PDV: DDI {pdv.get('A')!r} is not hex") from None
            if (d in MASS_RATE_DDIS or d in VOLUME_RATE_DDIS) and d not in found:
                found[d] = products.get(pdv.get("C"), "")
            seen.append(f"{d} ({_ddi_unit(d)[0]})")
    for d in (*MASS_RATE_DDIS, *VOLUME_RATE_DDIS):
        if d in found:
            return d, found[d], seen
    return None, "", seen


def _task_timelogs(ds: TaskDataSet, tsk: ET.Element, w: str, name: str, fs: _Files) -> None:
    from fieldrx.formats.timelog import read_timelog, timelog_summary

    for k, tlg in enumerate(tsk.findall("TLG")):
        ref = tlg.get("A", "")
        entry: dict[str, Any] = {"task": tsk.get("A", ""), "task_name": name, "timelog": ref}
        try:
            log = read_timelog(
                ref, fs.get(f"{ref}.XML", f"{w}/TLG[{k}]"), fs.get(f"{ref}.BIN", f"{w}/TLG[{k}]")
            )
            entry.update(timelog_summary(log))
        except FormatError as exc:
            entry["error"] = str(exc)
        ds.timelogs.append(entry)


def _zones(rx: RxIn, tzns: dict[int, ET.Element], w: str, zone_rate: Any) -> bool:
    """A zone prescription's polygons and rates; False when no zone has a polygon."""
    for code, z in sorted(tzns.items()):
        plns = enumerate(z.findall("PLN"))
        polys = [pln_polygon(p, f"{w}/TZN[{code}]/PLN[{k}]") for k, p in plns]
        if polys:
            rx.zones.append((zone_rate(code, w), shapely.union_all(shapely.make_valid(polys))))
    return bool(rx.zones)


def _check_grid(grds: list[ET.Element], w: str, ctx: _TaskCtx, tzns: dict[int, ET.Element]) -> str:
    """A skipped task's grid binary is still read (a broken one is an error); its size."""
    if not grds:
        return ""
    g = _grid(grds[0], f"{w}/GRD", ctx.fs, tzns, None, 0.0, None)
    rows, cols = g["rates"].shape
    layers = f"{g['layers']} layer{'s' if g['layers'] != 1 else ''}"
    kind = grds[0].get("I")
    return f"; its grid (type {kind}, {rows} x {cols} cells, {layers}) was read and is whole"


def _task(ds: TaskDataSet, tsk: ET.Element, w: str, ctx: _TaskCtx) -> None:
    name = (tsk.get("B") or "").strip() or f"Task {tsk.get('A')}"
    _task_timelogs(ds, tsk, w, name, ctx.fs)
    tzns: dict[int, ET.Element] = {}
    for z in tsk.findall("TZN"):
        tzns[attr_int(z, "A", f"{w}/TZN")] = z
    if not tzns:
        ds.skip(f"{w} {name}", "task without treatment zones (no prescription)")
        return
    ddi, product, seen = _rate_ddi(tzns, w, ctx.products)
    grds = tsk.findall("GRD")
    pfd = tsk.get("E")
    if pfd not in ctx.field_refs:
        why = f"task's partfield {pfd!r} has no boundary in the upload"
        ds.skip(f"{w} {name}", why + _check_grid(grds, w, ctx, tzns))
        return
    if ddi is None:
        _check_grid(grds, w, ctx, tzns)
        ds.skip(
            f"{w} {name}",
            "no mass- or volume-per-area rate (DDI 6 or 1) among "
            + (", ".join(sorted(set(seen))) or "no process data")
            + ": only mass rates (DDI 6) and, with a density, volume rates (DDI 1) "
            "become kg/ha",
        )
        return
    unit = "kg/ha"
    factor = MASS_RATE_DDIS.get(ddi, 0.0)
    if ddi in VOLUME_RATE_DDIS:
        unit = "l/ha"
        if ctx.density_kg_l is None:
            _check_grid(grds, w, ctx, tzns)
            ds.skip(
                f"{w} {name}",
                f"volume rate (DDI {ddi}, l/ha): give the product's density in kg/l "
                "(density_kg_l) to import it as kg/ha",
                needs_density=True,
            )
            return
        # mm^3/m^2 -> l/ha is x 0.01 (1e-6 l per 1e-4 ha); x density (kg/l) -> kg/ha
        factor = VOLUME_RATE_DDIS[ddi] * ctx.density_kg_l

    def zone_rate(code: int, where: str) -> float:
        z = tzns.get(code)
        if z is None:
            return 0.0
        for pdv in z.findall("PDV"):
            if int(pdv.get("A", "0"), 16) == ddi:
                return attr_num(pdv, "B", f"{where}/TZN[{code}]/PDV") * factor
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
        unit=unit,
        default_rate_kg_ha=default,
        density_kg_l=ctx.density_kg_l if unit == "l/ha" else None,
    )
    if grds:
        rx.grid = _grid(grds[0], f"{w}/GRD", ctx.fs, tzns, ddi, factor, zone_rate)
        rx.kind = f"grid type {grds[0].get('I')}"
    elif not _zones(rx, tzns, w, zone_rate):
        ds.skip(f"{w} {name}", "treatment zones without polygons or grid")
        return
    ds.prescriptions.append(rx)


def _grid(
    grd: ET.Element,
    w: str,
    fs: _Files,
    tzns: dict[int, ET.Element],
    ddi: int | None,
    factor: float,
    zone_rate: Any,
) -> dict[str, Any]:
    """The grid's geometry and rates; with ``ddi`` None only its binary is checked."""
    south, west = attr_num(grd, "A", w), attr_num(grd, "B", w)
    dlat, dlon = attr_num(grd, "C", w), attr_num(grd, "D", w)
    cols, rows = attr_int(grd, "E", w), attr_int(grd, "F", w)
    if not (0 < dlat <= 1 and 0 < dlon <= 1):
        raise FormatError(f"{w}: cell size {dlat} x {dlon} degrees is not in (0, 1]")
    if cols < 1 or rows < 1 or rows * cols > MAX_GRID_CELLS:
        raise FormatError(f"{w}: {rows} x {cols} cells (1..{MAX_GRID_CELLS} accepted)")
    kind = grd.get("I")
    fname = f"{grd.get('G', '')}.BIN"
    declared = grd.get("H")
    if declared is not None:
        size = attr_int(grd, "H", w)
        if size > MAX_BINARY_BYTES:
            raise FormatError(
                f"{w}: binary {fname} declared as {size} bytes (> {MAX_BINARY_BYTES}): refused"
            )
    data = fs.get(fname, w)
    if kind == "1":
        want = rows * cols
        if len(data) != want:
            raise FormatError(
                f"{w}: binary {fname} has {len(data)} bytes, {rows} x {cols} type-1 cells "
                f"need {want} (H says {declared})"
            )
        codes = np.frombuffer(data, dtype=np.uint8).reshape(rows, cols)
        rates = codes.astype(float)
        if zone_rate is not None:
            rates = np.asarray([zone_rate(c, w) for c in range(256)])[codes]
    elif kind == "2":
        code = attr_int(grd, "J", w)
        z = tzns.get(code)
        if z is None:
            raise FormatError(f"{w}: grid zone J={code} is not a TZN of the task")
        pdvs = [int(p.get("A", "0"), 16) for p in z.findall("PDV")]
        if ddi is not None and ddi not in pdvs:
            raise FormatError(f"{w}: TZN[{code}] has no PDV with DDI {ddi}")
        k = len(pdvs)
        want = rows * cols * 4 * k
        if len(data) != want:
            raise FormatError(
                f"{w}: binary {fname} has {len(data)} bytes, {rows} x {cols} cells x {k} "
                f"values x 4 need {want} (H says {declared})"
            )
        vals = np.frombuffer(data, dtype="<i4").reshape(rows, cols, k)
        rates_layers = k
        rates = vals[:, :, 0 if ddi is None else pdvs.index(ddi)].astype(float) * factor
    else:
        raise FormatError(f"{w}: grid type I={kind!r} (1 and 2 are defined)")
    note = None
    if declared is not None and int(declared) != len(data):
        # some writers put a wrong file length in H; the grid's own size decides
        note = (
            f"{w}: H declares {declared} bytes, binary {fname} has {len(data)}, which is "
            f"what the {rows} x {cols} grid needs: read as the grid says"
        )
    return {
        "south": south,
        "west": west,
        "dlat": dlat,
        "dlon": dlon,
        "rates": rates,
        "note": note,
        "layers": 1 if kind == "1" else rates_layers,
    }
