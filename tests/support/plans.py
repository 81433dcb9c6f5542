"""Shared helpers for the plan / prescription API tests."""

from __future__ import annotations

from tests.support import SMALL_PLOT, feature

API = "/api/v1"


def make_field(client, headers, geometry: dict | None = None, name: str = "Test field") -> int:
    r = client.post(
        f"{API}/fields", headers=headers, json=feature(geometry or SMALL_PLOT, name=name)
    )
    assert r.status_code == 201, r.text
    return r.json()["id"]


def make_plan(client, headers, field_id: int, **params) -> dict:
    body = {"swath_width_m": 2.3, "cell_length_m": 5.0, "heading": "longest_edge", **params}
    r = client.post(f"{API}/fields/{field_id}/plans", headers=headers, json=body)
    assert r.status_code == 201, r.text
    return r.json()


def rectangle(lon0: float, lat0: float, width_m: float, height_m: float) -> dict:
    """A lon/lat rectangle of about width_m x height_m (near lat0)."""
    import math

    dlon = width_m / (111_320.0 * math.cos(math.radians(lat0)))
    dlat = height_m / 110_574.0
    ring = [
        [lon0, lat0],
        [lon0 + dlon, lat0],
        [lon0 + dlon, lat0 + dlat],
        [lon0, lat0 + dlat],
        [lon0, lat0],
    ]
    return {"type": "Polygon", "coordinates": [ring]}
