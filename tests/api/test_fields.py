"""Fields API: GeoJSON in and out, validation with precise messages, paging and bbox."""

from __future__ import annotations

import copy

import pytest
from pyproj import Geod
from shapely.geometry import shape

from tests.support import FIELD_WITH_HOLE, SMALL_PLOT, feature

GEOD = Geod(ellps="WGS84")


def test_create_get_list_update_delete(client, org) -> None:
    h = org.headers()
    r = client.post("/api/v1/fields", headers=h, json=feature(FIELD_WITH_HOLE, crop="rape"))
    assert r.status_code == 201, r.text
    f = r.json()
    assert f["type"] == "Feature" and f["geometry"]["type"] == "MultiPolygon"
    assert f["properties"]["utm_epsg"] == 32649
    geod_area = abs(GEOD.geometry_area_perimeter(shape(FIELD_WITH_HOLE))[0])
    assert f["properties"]["area_m2"] == pytest.approx(geod_area, rel=1e-3)
    assert len(f["geometry"]["coordinates"][0]) == 2  # hole kept
    fid = f["id"]
    assert client.get(f"/api/v1/fields/{fid}", headers=h).json()["properties"]["crop"] == "rape"
    fc = client.get("/api/v1/fields", headers=h).json()
    assert fc["type"] == "FeatureCollection" and fc["total"] == 1
    r = client.patch(f"/api/v1/fields/{fid}", headers=h, json={"properties": {"name": "Renamed"}})
    assert r.json()["properties"]["name"] == "Renamed"
    r = client.patch(f"/api/v1/fields/{fid}", headers=h, json={"geometry": SMALL_PLOT})
    assert r.status_code == 200
    assert r.json()["properties"]["area_m2"] < 1000
    assert client.delete(f"/api/v1/fields/{fid}", headers=h).status_code == 204
    assert client.get(f"/api/v1/fields/{fid}", headers=h).status_code == 404


def test_orientation_normalised(client, org) -> None:
    cw = copy.deepcopy(SMALL_PLOT)
    cw["coordinates"][0] = list(reversed(cw["coordinates"][0]))
    r = client.post("/api/v1/fields", headers=org.headers(), json=feature(cw))
    ring = shape(
        {"type": "Polygon", "coordinates": r.json()["geometry"]["coordinates"][0]}
    ).exterior
    assert ring.is_ccw


def test_bbox_filter_and_paging(client, org) -> None:
    h = org.headers()
    for i in range(3):
        g = copy.deepcopy(SMALL_PLOT)
        g["coordinates"][0] = [[x + i * 0.01, y] for x, y in g["coordinates"][0]]
        assert (
            client.post("/api/v1/fields", headers=h, json=feature(g, name=f"F{i}")).status_code
            == 201
        )
    fc = client.get("/api/v1/fields?bbox=112.319,32.12,112.3205,32.14", headers=h).json()
    assert [f["properties"]["name"] for f in fc["features"]] == ["F0"]
    page = client.get("/api/v1/fields?limit=2&offset=2", headers=h).json()
    assert page["total"] == 3 and len(page["features"]) == 1
    assert client.get("/api/v1/fields?bbox=1,2,3", headers=h).status_code == 422
    assert client.get("/api/v1/fields?q=f1", headers=h).json()["total"] == 1


def _poly(coords: list) -> dict:
    return {"type": "Polygon", "coordinates": [coords]}


BAD = [
    ({"type": "Point", "coordinates": [112.3, 32.1]}, "not a Polygon or MultiPolygon", None),
    (
        _poly([[112.32, 32.13], [112.321, 32.13], [112.32, 32.13], [112.32, 32.13]]),
        "2 distinct vertices",
        None,
    ),
    (
        _poly(
            [
                [112.32, 32.13],
                [112.321, 32.131],
                [112.32, 32.131],
                [112.321, 32.13],
                [112.32, 32.13],
            ]
        ),
        "Self-intersection at (112.3205000, 32.1305000)",
        [112.3205, 32.1305],
    ),
    (
        _poly([[32.13, 112.32], [32.131, 112.32], [32.131, 112.321], [32.13, 112.32]]),
        "look swapped",
        None,
    ),
    (_poly([[200, 10], [201, 10], [201, 11], [200, 10]]), "out of range", None),
    (
        _poly([[112.32, 32.13], [112.32005, 32.13], [112.32005, 32.13005], [112.32, 32.13]]),
        "below the minimum",
        None,
    ),
    (_poly([[100, 10], [112, 10], [112, 20], [100, 10]]), "above the maximum of 10,000 ha", None),
]


@pytest.mark.parametrize(("geometry", "message", "location"), BAD)
def test_validation_messages(client, org, geometry, message, location) -> None:
    r = client.post("/api/v1/fields", headers=org.headers(), json=feature(geometry))
    assert r.status_code == 422, r.text
    body = r.json()
    assert message in body["detail"]
    if location:
        assert body["location"] == pytest.approx(location)
    assert client.get("/api/v1/fields", headers=org.headers()).json()["total"] == 0


def test_too_many_vertices(client, org) -> None:
    import math

    n = 20_001
    ring = [
        [
            112.32 + 0.001 * math.cos(2 * math.pi * i / n),
            32.13 + 0.001 * math.sin(2 * math.pi * i / n),
        ]
        for i in range(n)
    ]
    ring.append(ring[0])
    r = client.post("/api/v1/fields", headers=org.headers(), json=feature(_poly(ring)))
    assert r.status_code == 422
    assert "more than 20000 vertices" in r.json()["detail"]


def test_unknown_farm_rejected(client, org) -> None:
    r = client.post(
        "/api/v1/fields", headers=org.headers(), json=feature(SMALL_PLOT, farm_id=999999)
    )
    assert r.status_code == 422 and "farm 999999 not found" in r.json()["detail"]


def test_viewer_cannot_write(client, org) -> None:
    r = client.post("/api/v1/fields", headers=org.headers("viewer"), json=feature(SMALL_PLOT))
    assert r.status_code == 403
    assert client.get("/api/v1/fields", headers=org.headers("viewer")).status_code == 200
