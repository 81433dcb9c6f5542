"""A field's area does not depend on which way its rings wind.

``Geod.geometry_area_perimeter`` adds signed ring areas, so a hole wound like its
exterior was added (42,537 m² instead of 37,533 m² for the issue's field)."""

from __future__ import annotations

import math

import pytest
from fieldrx.geo.crs import epsg_for_geometry, plane_area_m2
from fieldrx.geo.validate import geodesic_area_m2, validate_boundary
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import shape

from tests.support import feature

LON0, LAT0 = 7.90, 51.75
DLON = 1.0 / (111_320.0 * math.cos(math.radians(LAT0)))  # degrees per metre east
DLAT = 1.0 / 111_200.0  # degrees per metre north


def _ring(x0: float, y0: float, w: float, h: float, ccw: bool) -> list[list[float]]:
    pts = [(x0, y0), (x0 + w, y0), (x0 + w, y0 + h), (x0, y0 + h)]
    if not ccw:
        pts = pts[::-1]
    ring = [[LON0 + x * DLON, LAT0 + y * DLAT] for x, y in pts]
    return ring + [ring[0]]


def _field(outer_ccw: bool, hole_ccw: bool) -> dict:
    """About 200 m x 200 m with a 50 m x 50 m hole (the issue's field)."""
    return {
        "type": "Polygon",
        "coordinates": [_ring(0, 0, 200, 200, outer_ccw), _ring(75, 75, 50, 50, hole_ccw)],
    }


def test_issue_field_area_same_for_every_winding(client, org) -> None:
    """POST the issue's field four ways: the stored area is the exterior minus the hole."""
    h = org.headers()
    areas = []
    for outer_ccw in (True, False):
        for hole_ccw in (True, False):
            geom = _field(outer_ccw, hole_ccw)
            r = client.post("/api/v1/fields", headers=h, json=feature(geom, name="w"))
            assert r.status_code == 201, r.text
            areas.append(r.json()["properties"]["area_m2"])
    outer = geodesic_area_m2(
        shape({"type": "Polygon", "coordinates": [_field(True, True)["coordinates"][0]]})
    )
    hole = geodesic_area_m2(
        shape({"type": "Polygon", "coordinates": [_field(True, True)["coordinates"][1]]})
    )
    assert outer - hole == pytest.approx(37_500, rel=0.01)
    # the stored area is the one basis, the field's UTM plane: within the scale factor
    # of the geodesic area, and exactly the plane area of exterior minus hole
    geom = shape(_field(True, True))
    plane = plane_area_m2(geom, epsg_for_geometry(geom))
    assert plane == pytest.approx(outer - hole, rel=2e-3)
    for a in areas:
        assert a == pytest.approx(plane, rel=1e-9)


@st.composite
def wound_multipolygons(draw):  # noqa: ANN201
    """Rectangles with up to 3 holes (and a second part), every ring wound at random."""
    parts = []
    for k in range(draw(st.integers(1, 2))):
        x0 = k * 1000.0
        w = draw(st.floats(150.0, 600.0))
        h = draw(st.floats(150.0, 600.0))
        rings = [_ring(x0, 0, w, h, draw(st.booleans()))]
        for i in range(draw(st.integers(0, 3))):
            hw = draw(st.floats(5.0, w / 4 - 2))
            hh = draw(st.floats(5.0, h - 20))
            rings.append(_ring(x0 + 10 + i * w / 4, 10, hw, hh, draw(st.booleans())))
        parts.append(rings)
    return {"type": "MultiPolygon", "coordinates": parts}


@settings(max_examples=60, deadline=None, derandomize=True)
@given(wound_multipolygons())
def test_area_independent_of_winding(geom: dict) -> None:
    """Property: the area equals the sum of exterior areas minus hole areas, each taken
    as a magnitude, for any winding of any ring; validation reports the same number."""
    expect = 0.0
    for part in geom["coordinates"]:
        sign = 1.0
        for ring in part:
            expect += sign * geodesic_area_m2(shape({"type": "Polygon", "coordinates": [ring]}))
            sign = -1.0
    assert geodesic_area_m2(shape(geom)) == pytest.approx(expect, rel=1e-9)
    flipped = {
        "type": "MultiPolygon",
        "coordinates": [[r[::-1] for r in part] for part in geom["coordinates"]],
    }
    v1, v2 = validate_boundary(geom), validate_boundary(flipped)
    g = shape(geom)
    plane = plane_area_m2(g, epsg_for_geometry(g))
    assert plane == pytest.approx(expect, rel=2e-3)  # the UTM scale factor, squared
    assert v1.area_m2 == pytest.approx(plane, rel=1e-9)
    assert v2.area_m2 == pytest.approx(plane, rel=1e-9)
    assert v1.geometry.area == pytest.approx(v2.geometry.area, rel=1e-12)
