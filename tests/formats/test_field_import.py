"""Field-boundary import from GeoJSON, KML/KMZ and zipped Shapefile."""

import io
import json
import zipfile

import pytest
import shapefile as pyshp
import shapely
from fieldrx.formats import FormatError
from fieldrx.formats.field_import import read_fields
from fieldrx.geo.crs import to_utm

SQ = shapely.Polygon(
    [(112.3230, 32.1340), (112.3250, 32.1340), (112.3250, 32.1355), (112.3230, 32.1355)],
    [[(112.3238, 32.1345), (112.3242, 32.1345), (112.3242, 32.1348), (112.3238, 32.1348)]],
)


def test_geojson_feature_collection():
    fc = {
        "type": "FeatureCollection",
        "features": [
            {
                "type": "Feature",
                "geometry": shapely.geometry.mapping(SQ),
                "properties": {"name": "North"},
            },
            {
                "type": "Feature",
                "geometry": shapely.geometry.mapping(shapely.MultiPolygon([SQ])),
                "properties": {"NAME": "South", "crop": "rape"},
            },
        ],
    }
    out = read_fields("f.geojson", json.dumps(fc).encode())
    assert [p["name"] for p, _ in out] == ["North", "South"]
    assert out[1][0]["crop"] == "rape"
    assert out[0][1].equals(SQ) and out[1][1].geom_type == "MultiPolygon"


def test_geojson_errors_name_feature_index():
    fc = {
        "type": "FeatureCollection",
        "features": [
            {"type": "Feature", "geometry": shapely.geometry.mapping(SQ), "properties": {}},
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [1, 2]},
                "properties": {},
            },
        ],
    }
    with pytest.raises(FormatError, match="feature 1: geometry type Point"):
        read_fields("f.json", json.dumps(fc).encode())
    projected = to_utm(SQ, 32649)
    bad = {"type": "Feature", "geometry": shapely.geometry.mapping(projected), "properties": {}}
    with pytest.raises(FormatError, match="feature 0: coordinates are not longitude/latitude"):
        read_fields("f.geojson", json.dumps(bad).encode())
    with pytest.raises(FormatError, match="not valid JSON"):
        read_fields("f.geojson", b"{nope")
    with pytest.raises(FormatError, match="unsupported file"):
        read_fields("f.gpkg", b"")


def _kml(placemarks):
    return (
        '<?xml version="1.0" encoding="UTF-8"?><kml xmlns="http://www.opengis.net/kml/2.2"><Document>'
        + placemarks
        + "</Document></kml>"
    ).encode()


def _ring(coords):
    return " ".join(f"{x},{y},0" for x, y in coords)


def test_kml_and_kmz():
    pm = (
        "<Placemark><name>Rape field</name><ExtendedData>"
        '<Data name="crop"><value>rape</value></Data>'
        "</ExtendedData><Polygon><outerBoundaryIs><LinearRing><coordinates>"
        + _ring(SQ.exterior.coords)
        + "</coordinates></LinearRing></outerBoundaryIs>"
        "<innerBoundaryIs><LinearRing><coordinates>"
        + _ring(SQ.interiors[0].coords)
        + "</coordinates></LinearRing></innerBoundaryIs></Polygon></Placemark>"
    )
    out = read_fields("f.kml", _kml(pm))
    assert out[0][0]["name"] == "Rape field" and out[0][0]["crop"] == "rape"
    assert out[0][1].equals(SQ)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("doc.kml", _kml(pm))
    assert read_fields("f.kmz", buf.getvalue())[0][1].equals(SQ)
    point = (
        "<Placemark><name>pin</name>"
        "<Point><coordinates>112.3,32.1</coordinates></Point></Placemark>"
    )
    with pytest.raises(FormatError, match="feature 1: Placemark has no Polygon"):
        read_fields("f.kml", _kml(pm + point))


def _shp_zip(geoms, names, prj=None, folder=""):
    shp, shx, dbf = io.BytesIO(), io.BytesIO(), io.BytesIO()
    w = pyshp.Writer(shp=shp, shx=shx, dbf=dbf, shapeType=pyshp.POLYGON)
    w.field("NAME", "C", 40)
    for g, n in zip(geoms, names, strict=True):
        w.shape(shapely.geometry.mapping(g))
        w.record(n)
    w.close()
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        z.writestr(folder + "fields.shp", shp.getvalue())
        z.writestr(folder + "fields.shx", shx.getvalue())
        z.writestr(folder + "fields.dbf", dbf.getvalue())
        if prj:
            z.writestr(folder + "fields.prj", prj)
    return out.getvalue()


def test_shapefile_zip_wgs84_and_projected():
    out = read_fields("f.zip", _shp_zip([SQ], ["A"]))
    assert out[0][0]["name"] == "A" and out[0][0]["NAME"] == "A"
    assert shapely.equals_exact(
        shapely.normalize(out[0][1]), shapely.normalize(SQ), tolerance=1e-12
    )
    from pyproj import CRS

    utm = to_utm(SQ, 32649)
    data = _shp_zip(
        [utm], ["B"], prj=CRS.from_epsg(32649).to_wkt(version="WKT1_ESRI"), folder="sub/"
    )
    back = read_fields("f.zip", data)[0][1]
    assert shapely.hausdorff_distance(back, SQ) < 1e-8
    with pytest.raises(FormatError, match="exactly one .shp"):
        read_fields("f.zip", _shp_zip([SQ], ["A"])[:0] or zipfile_with_nothing())


def zipfile_with_nothing():
    b = io.BytesIO()
    with zipfile.ZipFile(b, "w") as z:
        z.writestr("readme.txt", "no shapefile here")
    return b.getvalue()
