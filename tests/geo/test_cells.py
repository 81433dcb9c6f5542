"""The one cell type: centre rule, driving-line rule, views, GeoJSON writer, row selection."""

from __future__ import annotations

import json

import numpy as np
import pytest
import shapely
from fieldrx.geo.cells import Cells, cell_centres, cut_edge_midpoints
from fieldrx.geo.crs import to_wgs84

EPSG = 32633
X0, Y0 = 500000.0, 5800000.0


def test_centre_is_the_area_centroid_or_a_point_inside() -> None:
    rect = shapely.box(X0, Y0, X0 + 2.3, Y0 + 5)
    ell = shapely.Polygon(
        [(X0, Y0), (X0 + 10, Y0), (X0 + 10, Y0 + 1), (X0 + 1, Y0 + 1), (X0 + 1, Y0 + 10),
         (X0, Y0 + 10)]
    )  # fmt: skip
    holed = shapely.box(X0, Y0, X0 + 4, Y0 + 4).difference(
        shapely.box(X0 + 1, Y0 + 1, X0 + 3, Y0 + 3)
    )
    split = shapely.MultiPolygon(
        [shapely.box(X0, Y0, X0 + 1, Y0 + 1), shapely.box(X0 + 5, Y0, X0 + 6, Y0 + 1)]
    )
    polys = np.array([rect, ell, holed, split, shapely.Polygon()], dtype=object)
    c = cell_centres(polys)
    assert c[0] == pytest.approx([X0 + 1.15, Y0 + 2.5], abs=1e-9)  # shoelace, UTM magnitudes
    for i in (1, 2, 3):  # the centroid is outside these: a point on the surface instead
        assert not polys[i].contains(polys[i].centroid)
        assert polys[i].contains(shapely.Point(c[i])), i
    assert np.isnan(c[4]).all()


def test_drive_line_joins_the_cut_edge_midpoints() -> None:
    # rear-right, front-right, front-left, rear-left of a cell driven north
    c = np.array([[[2.3, 0.0], [2.3, 5.0], [0.0, 5.0], [0.0, 0.0]]])
    rear, front = cut_edge_midpoints(c)
    assert rear.tolist() == [[1.15, 0.0]] and front.tolist() == [[1.15, 5.0]]


def test_views_geojson_and_take() -> None:
    cells = Cells.rectangle(EPSG, X0, Y0, 2, 3, 2.3, 5.0)
    assert cells.index_in_swath.tolist() == [0, 1, 2, 0, 1, 2]
    np.testing.assert_allclose(cells.corners_wgs84[0], shapely.get_coordinates(
        to_wgs84(shapely.MultiPoint(cells.corners_utm[0]), EPSG)))  # fmt: skip
    rx = cells.with_rates(np.array([1.0, np.nan, 3.0, 4.0, 5.0, 6.0]), np.full(6, 2))
    assert rx.rate_kg_ha is not cells.rate_kg_ha and rx.polygons_utm is cells.polygons_utm
    fc = json.loads(
        rx.geojson_bytes(
            {"rate": rx.rate_kg_ha, "tag": ["a"] * 6, "flags": [["x"], [], ["x"], [], [], []]},
            {"version": 2},
        )
    )
    assert fc["properties"] == {"version": 2}
    f1 = fc["features"][1]
    assert f1["id"] == 1 and f1["properties"] == {"rate": None, "tag": "a", "flags": []}
    assert fc["features"][0]["properties"]["flags"] == ["x"]
    geom = shapely.geometry.shape(fc["features"][0]["geometry"])
    assert geom.equals_exact(rx.polygons_wgs84()[0], 1e-9)
    sub = rx.take(np.array([4, 5]))
    assert sub.seq.tolist() == [4, 5] and sub.rate_kg_ha.tolist() == [5.0, 6.0]
    assert sub.polygons_wgs84()[0] is rx.polygons_wgs84()[4]  # views carried along
    with pytest.raises(ValueError, match="column rate has 2 rows for 6 cells"):
        rx.geojson_features({"rate": [1, 2]})
    no_zone = Cells.rectangle(0, X0, Y0, 1, 1)
    with pytest.raises(ValueError, match="no UTM zone"):
        no_zone.polygons_wgs84()
    with pytest.raises(ValueError, match="swath has 1 rows, expected 2"):
        Cells(EPSG, [0, 1], [0], [0, 1], np.zeros((2, 4, 2)), [1, 1], np.full(2, None))
