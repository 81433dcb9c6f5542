"""Field boundaries from GeoJSON, KML/KMZ or a zipped Shapefile -> shapely WGS84 polygons.

``read_fields(filename, data)`` returns ``[(properties, geometry)]`` with
every geometry a 2-D Polygon or MultiPolygon in lon/lat and ``properties``
holding at least ``name`` (from a name/NAME/Name attribute or the KML
``<name>``; "" when absent). Any problem raises ``FormatError`` naming the
feature index (0-based, in file order) so that an import is all-or-nothing.
Geometry validity (self-intersections, tiny areas) is left to
``fieldrx.geo.validate``; this module only reads.
"""

from __future__ import annotations

import io
import json
import xml.etree.ElementTree as ET
import zipfile
from typing import Any

import numpy as np
import shapefile as pyshp
import shapely
from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError
from shapely.geometry import MultiPolygon, Polygon, shape

from fieldrx.formats import FormatError
from fieldrx.registry import Registry

MAX_FEATURES = 10_000
MAX_INFLATED_BYTES = 256 * 1024 * 1024  # all members of one archive together, decompressed
_CHUNK = 1024 * 1024
_NAME_KEYS = ("name", "Name", "NAME", "field_name", "FIELD_NAME", "title")


def _name_of(props: dict[str, Any]) -> str:
    for k in _NAME_KEYS:
        v = props.get(k)
        if v not in (None, ""):
            return str(v).strip()
    return ""


def _check_geom(geom: Any, i: int) -> Polygon | MultiPolygon:
    if geom is None or geom.is_empty:
        raise FormatError(f"feature {i}: empty geometry")
    geom = shapely.force_2d(geom)
    if geom.geom_type == "GeometryCollection":
        parts = [g for g in geom.geoms if g.geom_type in ("Polygon", "MultiPolygon")]
        if len(parts) != len(geom.geoms) or not parts:
            raise FormatError(f"feature {i}: geometry collection holds non-polygon parts")
        geom = shapely.union_all(parts) if len(parts) > 1 else parts[0]
    if geom.geom_type not in ("Polygon", "MultiPolygon"):
        raise FormatError(
            f"feature {i}: geometry type {geom.geom_type} is not a Polygon or MultiPolygon"
        )
    x0, y0, x1, y1 = geom.bounds
    if not (-180 <= x0 <= x1 <= 180 and -90 <= y0 <= y1 <= 90):
        raise FormatError(
            f"feature {i}: coordinates are not longitude/latitude (bounds {geom.bounds}); "
            "projected data needs its .prj"
        )
    return geom


def _finish(items: list[tuple[dict[str, Any], Any]]) -> list[tuple[dict[str, Any], Any]]:
    if not items:
        raise FormatError("the file contains no field boundaries")
    if len(items) > MAX_FEATURES:
        raise FormatError(f"too many features ({len(items)} > {MAX_FEATURES})")
    out = []
    for i, (props, geom) in enumerate(items):
        p = dict(props)
        p["name"] = _name_of(p)
        out.append((p, _check_geom(geom, i)))
    return out


# GeoJSON -------------------------------------------------------------------


def read_geojson_fields(data: bytes | str) -> list[tuple[dict[str, Any], Any]]:
    try:
        obj = json.loads(data)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise FormatError(f"not valid JSON: {exc}") from exc
    if not isinstance(obj, dict):
        raise FormatError("GeoJSON must be an object")
    t = obj.get("type")
    if t == "FeatureCollection":
        feats = obj.get("features")
        if not isinstance(feats, list):
            raise FormatError("FeatureCollection without a 'features' list")
    elif t == "Feature":
        feats = [obj]
    elif t in ("Polygon", "MultiPolygon", "GeometryCollection"):
        feats = [{"type": "Feature", "geometry": obj, "properties": {}}]
    else:
        raise FormatError(f"unsupported GeoJSON type {t!r}")
    items: list[tuple[dict[str, Any], Any]] = []
    for i, f in enumerate(feats):
        if not isinstance(f, dict) or f.get("type") != "Feature":
            raise FormatError(f"feature {i}: not a GeoJSON Feature")
        props = f.get("properties") or {}
        if not isinstance(props, dict):
            raise FormatError(f"feature {i}: properties must be an object")
        g = f.get("geometry")
        if not isinstance(g, dict):
            raise FormatError(f"feature {i}: missing geometry")
        try:
            geom = shape(g)
        except (ValueError, TypeError, AttributeError, KeyError, IndexError) as exc:
            raise FormatError(f"feature {i}: bad geometry ({exc})") from exc
        items.append((props, geom))
    return _finish(items)


# KML / KMZ -------------------------------------------------------------------


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _children(el: ET.Element, name: str) -> list[ET.Element]:
    return [c for c in el if _local(c.tag) == name]


def _descendants(el: ET.Element, name: str) -> list[ET.Element]:
    return [c for c in el.iter() if _local(c.tag) == name]


def _kml_ring(el: ET.Element, i: int) -> list[tuple[float, float]]:
    rings = _descendants(el, "coordinates")
    if not rings or not (rings[0].text or "").strip():
        raise FormatError(f"feature {i}: LinearRing without coordinates")
    pts = []
    for tok in (rings[0].text or "").split():
        parts = tok.split(",")
        try:
            pts.append((float(parts[0]), float(parts[1])))
        except (ValueError, IndexError) as exc:
            raise FormatError(f"feature {i}: bad KML coordinate {tok!r}") from exc
    if len(pts) < 4:
        raise FormatError(f"feature {i}: a ring needs at least 4 points, got {len(pts)}")
    return pts


def _kml_polygon(el: ET.Element, i: int) -> Polygon:
    outer = _children(el, "outerBoundaryIs")
    if not outer:
        raise FormatError(f"feature {i}: Polygon without outerBoundaryIs")
    shell = _kml_ring(outer[0], i)
    holes = [_kml_ring(h, i) for h in _children(el, "innerBoundaryIs")]
    return Polygon(shell, holes)


def read_kml_fields(data: bytes) -> list[tuple[dict[str, Any], Any]]:
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise FormatError(f"not valid KML/XML: {exc}") from exc
    items: list[tuple[dict[str, Any], Any]] = []
    for i, pm in enumerate(_descendants(root, "Placemark")):
        props: dict[str, Any] = {}
        for d in _descendants(pm, "Data"):
            vals = _children(d, "value")
            props[d.get("name", "")] = (vals[0].text or "").strip() if vals else ""
        for sd in _descendants(pm, "SimpleData"):
            props[sd.get("name", "")] = (sd.text or "").strip()
        names = _children(pm, "name")
        if names and (names[0].text or "").strip():
            props["name"] = names[0].text.strip()  # type: ignore[union-attr]
        desc = _children(pm, "description")
        if desc and (desc[0].text or "").strip():
            props.setdefault("description", desc[0].text.strip())  # type: ignore[union-attr]
        polys = [_kml_polygon(p, i) for p in _descendants(pm, "Polygon")]
        if not polys:
            kinds = sorted({_local(c.tag) for c in pm.iter()} & {"Point", "LineString"})
            found = ", ".join(kinds) or "no geometry"
            raise FormatError(f"feature {i}: Placemark has no Polygon ({found})")
        geom = polys[0] if len(polys) == 1 else MultiPolygon(polys)
        items.append((props, geom))
    return _finish(items)


# Archives ---------------------------------------------------------------------


class _Archive:
    """A zip upload read with a budget on decompressed bytes.

    A 1 MB zip can inflate to 1 GiB (a "zip bomb"): the sizes declared in the
    central directory are checked first, and each member is then inflated in
    1 MiB chunks counted against what is left of ``MAX_INFLATED_BYTES``
    (zipfile itself stops at the declared size and checks the CRC, so a lying
    header cannot get past the count either).
    """

    def __init__(self, data: bytes, what: str = "the zip") -> None:
        try:
            self.z = zipfile.ZipFile(io.BytesIO(data))
        except zipfile.BadZipFile as exc:
            raise FormatError(f"{what} is not a zip file") from exc
        self.what = what
        self.left = MAX_INFLATED_BYTES

    def namelist(self) -> list[str]:
        return self.z.namelist()

    def read(self, name: str) -> bytes:
        info = self.z.getinfo(name)
        if info.file_size > self.left:
            raise self._too_big(name)
        buf = bytearray()
        try:
            with self.z.open(info) as f:
                while chunk := f.read(_CHUNK):
                    buf += chunk
                    if len(buf) > self.left:
                        raise self._too_big(name)
        except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, OSError) as exc:
            raise FormatError(f"cannot read {name} from {self.what}: {exc}") from exc
        self.left -= len(buf)
        return bytes(buf)

    def _too_big(self, name: str) -> FormatError:
        return FormatError(
            f"{self.what} inflates to more than {MAX_INFLATED_BYTES // (1024 * 1024)} MiB "
            f"(at member {name}); refused"
        )


# Shapefile ---------------------------------------------------------------------


def _xy_fn(tr: Transformer) -> Any:
    def fn(c: np.ndarray) -> np.ndarray:
        return np.column_stack(tr.transform(c[:, 0], c[:, 1]))

    return fn


def read_shapefile_zip_fields(data: bytes) -> list[tuple[dict[str, Any], Any]]:
    z = _Archive(data, "the Shapefile upload")
    names = [n for n in z.namelist() if not n.startswith("__MACOSX") and not n.endswith("/")]
    shps = [n for n in names if n.lower().endswith(".shp")]
    if not shps and any(
        n.replace("\\", "/").rsplit("/", 1)[-1].upper() == "TASKDATA.XML" for n in names
    ):
        raise FormatError(
            "this is an ISO 11783-10 TASKDATA set, not a Shapefile: import it with "
            "POST /api/v1/imports/isoxml (fields with holes, farms and prescriptions)"
        )
    if len(shps) != 1:
        raise FormatError(f"the zip must hold exactly one .shp file, found {len(shps)}")
    base = shps[0][:-4]
    lower = {n.lower(): n for n in names}

    def member(ext: str) -> bytes | None:
        n = lower.get((base + ext).lower())
        return z.read(n) if n else None

    shp, shx, dbf, prj = member(".shp"), member(".shx"), member(".dbf"), member(".prj")
    cpg = member(".cpg")
    if dbf is None:
        raise FormatError(f"{base}.dbf is missing from the zip")
    encoding = "utf-8"
    if cpg:
        encoding = cpg.decode("ascii", "ignore").strip() or "utf-8"
    try:
        r = pyshp.Reader(
            shp=io.BytesIO(shp or b""),
            shx=io.BytesIO(shx) if shx else None,
            dbf=io.BytesIO(dbf),
            encoding=encoding,
            encodingErrors="replace",
        )
    except Exception as exc:  # pyshp raises its own and struct errors on corrupt files
        raise FormatError(f"cannot read the shapefile: {exc}") from exc
    transformer = None
    if prj:
        try:
            crs = CRS.from_wkt(prj.decode("utf-8", "replace"))
        except CRSError as exc:
            raise FormatError(f"cannot understand {base}.prj: {exc}") from exc
        if not crs.equals(CRS.from_epsg(4326), ignore_axis_order=True):
            transformer = Transformer.from_crs(crs, 4326, always_xy=True)
    field_names = [f[0] for f in r.fields[1:]]
    items: list[tuple[dict[str, Any], Any]] = []
    for i, sr in enumerate(r.iterShapeRecords()):
        if sr.shape.shapeType in (pyshp.NULL,):
            raise FormatError(f"feature {i}: empty geometry")
        if sr.shape.shapeType not in (pyshp.POLYGON, pyshp.POLYGONZ, pyshp.POLYGONM):
            raise FormatError(f"feature {i}: shape type {sr.shape.shapeTypeName} is not a polygon")
        try:
            geom = shape(sr.shape.__geo_interface__)
        except Exception as exc:
            raise FormatError(f"feature {i}: bad polygon ({exc})") from exc
        if transformer is not None:
            geom = shapely.transform(geom, _xy_fn(transformer))
        props = {k: v for k, v in zip(field_names, list(sr.record), strict=False)}
        items.append((props, geom))
    return _finish(items)


class FieldFile:
    """One file format of field boundaries that ``read_fields`` takes, by name ending."""

    name: str = ""
    label: str = ""  # how the refusal of an unknown file names it
    extensions: tuple[str, ...] = ()

    def read(self, data: bytes) -> list[tuple[dict[str, Any], Any]]:
        raise NotImplementedError


FIELD_FILE_FORMATS: Registry[FieldFile] = Registry("field file format")


@FIELD_FILE_FORMATS.register
class GeoJsonFields(FieldFile):
    name, label, extensions = "geojson", ".geojson/.json", (".geojson", ".json")

    def read(self, data: bytes) -> list[tuple[dict[str, Any], Any]]:
        return read_geojson_fields(data)


@FIELD_FILE_FORMATS.register
class KmlFields(FieldFile):
    name, label, extensions = "kml", ".kml", (".kml",)

    def read(self, data: bytes) -> list[tuple[dict[str, Any], Any]]:
        return read_kml_fields(data)


@FIELD_FILE_FORMATS.register
class KmzFields(FieldFile):
    name, label, extensions = "kmz", ".kmz", (".kmz",)

    def read(self, data: bytes) -> list[tuple[dict[str, Any], Any]]:
        z = _Archive(data, "the KMZ")
        kmls = [n for n in z.namelist() if n.lower().endswith(".kml")]
        if not kmls:
            raise FormatError("KMZ holds no .kml document")
        doc = "doc.kml" if "doc.kml" in kmls else kmls[0]
        return read_kml_fields(z.read(doc))


@FIELD_FILE_FORMATS.register
class ShapefileFields(FieldFile):
    name, label, extensions = "shapefile", "a zipped Shapefile (.zip)", (".zip",)

    def read(self, data: bytes) -> list[tuple[dict[str, Any], Any]]:
        return read_shapefile_zip_fields(data)


def read_fields(filename: str, data: bytes) -> list[tuple[dict[str, Any], Any]]:
    """Field boundaries from an upload in one of ``FIELD_FILE_FORMATS``, by its name's ending."""
    name = (filename or "").lower()
    for fmt in FIELD_FILE_FORMATS:
        if name.endswith(fmt.extensions):
            return fmt.read(data)
    labels = [f.label for f in FIELD_FILE_FORMATS]
    expected = ", ".join(labels[:-1]) + " or " + labels[-1]
    raise FormatError(f"unsupported file {filename!r}: expected {expected}")
