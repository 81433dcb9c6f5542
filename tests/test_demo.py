"""The demo data that `make run` loads: sign in with the printed credentials and read the field."""

from __future__ import annotations

import pytest
from fieldrx.demo import DEMO_EMAIL, DEMO_FIELD, DEMO_PASSWORD, seed_demo
from pyproj import Geod
from shapely.geometry import shape


def test_demo_field_area_matches_geodesic(client, db) -> None:
    info = seed_demo(db)
    again = seed_demo(db)  # idempotent
    assert (again.field_id, again.machine_id) == (info.field_id, info.machine_id)
    r = client.post("/api/v1/auth/login", json={"email": DEMO_EMAIL, "password": DEMO_PASSWORD})
    assert r.status_code == 200, r.text
    h = {"Authorization": f"Bearer {r.json()['access_token']}"}
    fc = client.get("/api/v1/fields", headers=h).json()
    assert fc["total"] == 1
    f = fc["features"][0]
    lon, lat = shape(f["geometry"]).centroid.coords[0]
    assert abs(lat - 32.13) < 0.01 and abs(lon - 112.32) < 0.01
    geodesic = abs(Geod(ellps="WGS84").geometry_area_perimeter(shape(DEMO_FIELD))[0])
    assert f["properties"]["area_m2"] == pytest.approx(geodesic, rel=1e-3)
    machines = client.get("/api/v1/machines", headers=h).json()["items"]
    assert machines[0]["width_m"] == 2.3 and machines[0]["lag_s"] == 1.52
    # an explicit calibration: seed 001 eq. 1 (q0 = 237.2 r - 404.4 g/min, 30..130 r/min)
    assert machines[0]["calibration"] == {
        "kind": "linear",
        "slope_g_min_per_rpm": 237.2,
        "intercept_g_min": -404.4,
        "min_rpm": 30.0,
        "max_rpm": 130.0,
    }
