"""ISO 11783-10 TASKDATA in: one partfield (``PFD``) as a field, and the XML readers it is
built from. The boundary is the union of the ``PLN`` of type 1, each ring from ``LSG``
type 1 (exterior) and type 2 (interior = hole); other polygons, lines, guidance patterns
and points are kept with the field as labelled GeoJSON features. Every problem is a
``FormatError`` naming the element (``isoxml_import`` reads the rest of the file).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon

from fieldrx.formats import FormatError


@dataclass
class FieldIn:
    ref: str
    name: str
    farm_ref: str | None
    boundary: Polygon | MultiPolygon
    declared_area_m2: float | None
    # guidance lines, obstacles and other annotations (GeoJSON features, lon/lat)
    features: list[dict[str, Any]] = field(default_factory=list)


def attr_num(el: ET.Element, attr: str, where: str) -> float:
    v = el.get(attr)
    try:
        x = float(v)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise FormatError(f"{where}: attribute {attr}={v!r} is not a number") from None
    if not np.isfinite(x):
        raise FormatError(f"{where}: attribute {attr}={v!r} is not finite")
    return x


def attr_int(el: ET.Element, attr: str, where: str) -> int:
    x = attr_num(el, attr, where)
    if x != int(x):
        raise FormatError(f"{where}: attribute {attr}={el.get(attr)!r} is not an integer")
    return int(x)


def _point(p: ET.Element, w: str) -> tuple[float, float]:
    lat, lon = attr_num(p, "C", w), attr_num(p, "D", w)
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise FormatError(f"{w}: position {lat}, {lon} is not latitude/longitude")
    return lon, lat


def _ring(lsg: ET.Element, where: str) -> list[tuple[float, float]]:
    return [_point(p, f"{where}/PNT[{k}]") for k, p in enumerate(lsg.findall("PNT"))]


def _rings(pln: ET.Element, where: str) -> tuple[list[tuple[float, float]] | None, list[Any]]:
    """A PLN's exterior ring (LSG A=1, or None) and its interior rings (LSG A=2)."""
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
    return shell, holes


def pln_polygon(pln: ET.Element, where: str) -> Polygon:
    shell, holes = _rings(pln, where)
    if shell is None:
        raise FormatError(f"{where}: polygon without an exterior ring (LSG A=1)")
    return Polygon(shell, holes)


def _attach_holes(polys: list[Polygon], holes: list[tuple[Any, str]]) -> list[Polygon]:
    """Holes written as PLN of their own (only LSG A=2, as some terminals export them)
    join the exterior polygon that contains them: ISO 11783-10 defines a PLN's interior
    rings as holes of its exterior, and a partfield's boundary is the union of its
    type-1 PLNs, so the hole belongs to whichever exterior surrounds it."""
    shells = [list(p.exterior.coords) for p in polys]
    inner: list[list[Any]] = [[list(r.coords) for r in p.interiors] for p in polys]
    for ring, where in holes:
        rp = Polygon(ring)
        owner = next(
            (
                i
                for i, p in enumerate(polys)
                if Polygon(p.exterior).contains(rp.representative_point())
            ),
            None,
        )
        if owner is None:
            raise FormatError(
                f"{where}: a hole (LSG A=2) outside every exterior ring of the partfield"
            )
        inner[owner].append(ring)
    return [Polygon(s, h) for s, h in zip(shells, inner, strict=True)]


# ISO 11783-10 PLN A, LSG A and PNT A type codes, for the kept features' labels
PLN_TYPES = {2: "treatment zone", 3: "water surface", 4: "building", 5: "road", 6: "obstacle",
             7: "flag", 8: "other", 9: "main field", 10: "headland", 11: "buffer zone",
             12: "windbreak"}  # fmt: skip
LSG_TYPES = {3: "tram line", 4: "sampling route", 5: "guidance pattern", 6: "drainage",
             7: "fence", 8: "flag", 9: "obstacle"}  # fmt: skip
PNT_TYPES = {1: "flag", 2: "other", 3: "field access", 4: "storage", 5: "obstacle",
             6: "guidance reference A", 7: "guidance reference B", 8: "guidance reference center",
             9: "guidance point", 10: "partfield reference point", 11: "homebase"}  # fmt: skip


def _type_name(table: dict[int, str], code: str | None) -> str:
    try:
        return table.get(int(code or ""), f"type {code}")
    except ValueError:
        return f"type {code}"


def _feature(geom: Any, kind: str, type_name: str, name: str, where: str) -> dict[str, Any]:
    return {
        "type": "Feature",
        "geometry": shapely.geometry.mapping(geom),
        "properties": {"kind": kind, "type": type_name, "name": name, "source": where},
    }


def _line(lsg: ET.Element, where: str) -> Any:
    pts = _ring(lsg, where)
    if len(pts) == 1:
        return shapely.Point(pts[0])
    if not pts:
        raise FormatError(f"{where}: a line without points")
    return shapely.LineString(pts)


def read_partfield(pfd: ET.Element, w: str) -> FieldIn | None:
    """One partfield: its boundary and the features kept with it (see module docstring)."""
    polys: list[Polygon] = []
    holes: list[tuple[Any, str]] = []
    features: list[dict[str, Any]] = []
    for k, pln in enumerate(pfd.findall("PLN")):
        pw = f"{w}/PLN[{k}]"
        shell, inner = _rings(pln, pw)
        if pln.get("A") == "1":
            if shell is None:
                holes.extend((r, pw) for r in inner)
            else:
                polys.append(Polygon(shell, inner))
        elif shell is not None or inner:
            poly = Polygon(shell, inner) if shell is not None else Polygon(inner[0])
            kind = _type_name(PLN_TYPES, pln.get("A"))
            features.append(_feature(poly, "polygon", kind, pln.get("B") or "", pw))
    for k, ggp in enumerate(pfd.findall("GGP")):
        for j, gpn in enumerate(ggp.findall("GPN")):
            for i, lsg in enumerate(gpn.findall("LSG")):
                gw = f"{w}/GGP[{k}]/GPN[{j}]/LSG[{i}]"
                name = gpn.get("B") or ggp.get("B") or gpn.get("A") or ""
                features.append(_feature(_line(lsg, gw), "guidance", "guidance pattern", name, gw))
    for k, lsg in enumerate(pfd.findall("LSG")):
        lw = f"{w}/LSG[{k}]"
        kind = _type_name(LSG_TYPES, lsg.get("A"))
        features.append(_feature(_line(lsg, lw), "line", kind, lsg.get("B") or "", lw))
    for k, pnt in enumerate(pfd.findall("PNT")):
        pw = f"{w}/PNT[{k}]"
        pt = _point(pnt, pw)
        kind = _type_name(PNT_TYPES, pnt.get("A"))
        features.append(_feature(shapely.Point(pt), "point", kind, pnt.get("B") or "", pw))
    if not polys:
        if holes:
            raise FormatError(f"{holes[0][1]}: holes (LSG A=2) without an exterior ring")
        return None
    if holes:
        polys = _attach_holes(polys, holes)
    geom: Polygon | MultiPolygon = polys[0] if len(polys) == 1 else MultiPolygon(polys)
    area = pfd.get("D")
    return FieldIn(
        pfd.get("A", ""),
        (pfd.get("C") or "").strip() or f"Partfield {pfd.get('A')}",
        pfd.get("F"),
        geom,
        float(area) if area and area.isdigit() else None,
        features,
    )
