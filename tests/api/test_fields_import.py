"""Bulk field import: GeoJSON FeatureCollection, KML, zipped Shapefile; all fields or none."""

from __future__ import annotations

import io
import json
import zipfile

import pytest
import shapefile  # pyshp
from shapely.geometry import shape
from shapely.geometry.polygon import orient

from tests.support import FIELD_WITH_HOLE, SMALL_PLOT

BOWTIE = {
    "type": "Polygon",
    "coordinates": [
        [[112.32, 32.13], [112.321, 32.131], [112.32, 32.131], [112.321, 32.13], [112.32, 32.13]]
    ],
}


def _fc(*geoms: dict) -> bytes:
    feats = [
        {"type": "Feature", "geometry": g, "properties": {"name": f"Imported {i}", "crop": "rape"}}
        for i, g in enumerate(geoms)
    ]
    return json.dumps({"type": "FeatureCollection", "features": feats}).encode()


def _kml(*geoms: dict) -> bytes:
    marks = []
    for i, g in enumerate(geoms):
        rings = g["coordinates"]
        outer = " ".join(f"{x},{y},0" for x, y in rings[0])
        inner = "".join(
            "<innerBoundaryIs><LinearRing><coordinates>"
            + " ".join(f"{x},{y},0" for x, y in r)
            + "</coordinates></LinearRing></innerBoundaryIs>"
            for r in rings[1:]
        )
        marks.append(
            f"<Placemark><name>KML {i}</name><Polygon><outerBoundaryIs><LinearRing><coordinates>"
            f"{outer}</coordinates></LinearRing></outerBoundaryIs>{inner}</Polygon></Placemark>"
        )
    return (
        '<?xml version="1.0" encoding="UTF-8"?><kml xmlns="http://www.opengis.net/kml/2.2">'
        f"<Document>{''.join(marks)}</Document></kml>"
    ).encode()


WGS84_PRJ = (
    'GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,298.257223563]],'
    'PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]]'
)


def _shp_zip(*geoms: dict) -> bytes:
    shp, shx, dbf = io.BytesIO(), io.BytesIO(), io.BytesIO()
    with shapefile.Writer(shp=shp, shx=shx, dbf=dbf, shapeType=shapefile.POLYGON) as w:
        w.field("NAME", "C", 50)
        for i, g in enumerate(geoms):
            p = orient(shape(g), sign=-1.0)  # shapefile: outer ring clockwise, holes not
            w.poly([list(p.exterior.coords)] + [list(r.coords) for r in p.interiors])
            w.record(f"SHP {i}")
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("fields.shp", shp.getvalue())
        z.writestr("fields.shx", shx.getvalue())
        z.writestr("fields.dbf", dbf.getvalue())
        z.writestr("fields.prj", WGS84_PRJ)
    return buf.getvalue()


@pytest.mark.parametrize(
    ("filename", "maker", "prefix"),
    [
        ("fields.geojson", _fc, "Imported"),
        ("fields.kml", _kml, "KML"),
        ("fields.zip", _shp_zip, "SHP"),
    ],
)
def test_import_all(client, org, filename, maker, prefix) -> None:
    r = client.post(
        "/api/v1/fields/import",
        headers=org.headers(),
        files={"file": (filename, maker(SMALL_PLOT, FIELD_WITH_HOLE))},
    )
    assert r.status_code == 201, r.text
    assert r.json()["imported"] == 2
    fc = client.get("/api/v1/fields", headers=org.headers()).json()
    names = sorted(f["properties"]["name"] for f in fc["features"])
    assert names == [f"{prefix} 0", f"{prefix} 1"]
    holed = next(f for f in fc["features"] if f["properties"]["name"].endswith("1"))
    assert len(holed["geometry"]["coordinates"][0]) == 2  # the hole survived the round trip
    assert 100_000 < holed["properties"]["area_m2"] < 120_000


@pytest.mark.parametrize(
    ("filename", "maker"),
    [("bad.geojson", _fc), ("bad.kml", _kml), ("bad.zip", _shp_zip)],
)
def test_import_is_all_or_nothing(client, org, filename, maker) -> None:
    r = client.post(
        "/api/v1/fields/import",
        headers=org.headers(),
        files={"file": (filename, maker(SMALL_PLOT, BOWTIE))},
    )
    assert r.status_code == 422, r.text
    body = r.json()
    assert body["feature_index"] == 1
    assert "feature 1" in body["detail"] and "Self-intersection" in body["detail"]
    assert client.get("/api/v1/fields", headers=org.headers()).json()["total"] == 0


def test_import_garbage(client, org) -> None:
    r = client.post(
        "/api/v1/fields/import", headers=org.headers(), files={"file": ("x.kml", b"<kml><oops")}
    )
    assert r.status_code == 422
    r = client.post(
        "/api/v1/fields/import", headers=org.headers(), files={"file": ("x.txt", b"hello")}
    )
    assert r.status_code == 422
    assert client.get("/api/v1/fields", headers=org.headers()).json()["total"] == 0


def test_import_needs_writer(client, org) -> None:
    r = client.post(
        "/api/v1/fields/import",
        headers=org.headers("viewer"),
        files={"file": ("f.geojson", _fc(SMALL_PLOT))},
    )
    assert r.status_code == 403
