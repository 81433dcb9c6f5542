"""Farms and machines CRUD, device tokens."""

from __future__ import annotations

from tests.support import SEED001_CAL, machine_body


def test_farm_crud(client, org) -> None:
    h = org.headers()
    r = client.post("/api/v1/farms", headers=h, json={"name": "Home farm", "notes": "n"})
    assert r.status_code == 201
    fid = r.json()["id"]
    assert client.get("/api/v1/farms", headers=h).json()["total"] == 1
    assert (
        client.patch(f"/api/v1/farms/{fid}", headers=h, json={"name": "Renamed"}).json()["name"]
        == "Renamed"
    )
    assert client.post("/api/v1/farms", headers=h, json={"name": ""}).status_code == 422
    assert client.delete(f"/api/v1/farms/{fid}", headers=h).status_code == 204
    assert client.get(f"/api/v1/farms/{fid}", headers=h).status_code == 404


MACHINE = machine_body("T1")


def test_machine_without_calibration_is_422_naming_the_missing_fields(client, org) -> None:
    """A machine added without calibration got seed 001's (169 kg/ha at 12 m)."""
    h = org.headers()
    r = client.post("/api/v1/machines", headers=h, json={"name": "T12", "width_m": 12.0})
    assert r.status_code == 422, r.text
    assert "calibration: Field required" in r.json()["detail"]
    assert "lag_s: Field required" in r.json()["detail"]
    partial = {"slope_g_min_per_rpm": 237.2}
    r = client.post("/api/v1/machines", headers=h, json={**MACHINE, "calibration": partial})
    detail = r.json()["detail"]
    assert r.status_code == 422
    for name in ("intercept_g_min", "min_rpm", "max_rpm"):
        assert f"{name}: Field required" in detail
    for cal, needle in (
        ({**SEED001_CAL, "max_rpm": 20}, "must be greater than min_rpm"),
        ({**SEED001_CAL, "min_rpm": 1}, "a * min_rpm + b must be > 0"),
        ({**SEED001_CAL, "slope_g_min_per_rpm": 0}, "slope_g_min_per_rpm"),
    ):
        r = client.post("/api/v1/machines", headers=h, json={**MACHINE, "calibration": cal})
        assert r.status_code == 422 and needle in r.json()["detail"], r.text
    assert client.get("/api/v1/machines", headers=h).json()["total"] == 0
    # a 12 m spreader with its own calibration keeps it exactly
    cal = {"slope_g_min_per_rpm": 900.0, "intercept_g_min": -500.0, "min_rpm": 10, "max_rpm": 150}
    r = client.post("/api/v1/machines", headers=h, json=machine_body("T12", 12.0, calibration=cal))
    assert r.status_code == 201, r.text
    assert r.json()["calibration"] == {"kind": "linear", **cal}


def test_machine_crud_and_validation(client, org) -> None:
    h = org.headers()
    r = client.post("/api/v1/machines", headers=h, json=MACHINE)
    assert r.status_code == 201, r.text
    m = r.json()
    assert m["calibration"] == SEED001_CAL
    assert m["controller"]["name"] == "ladrc"
    r = client.patch(f"/api/v1/machines/{m['id']}", headers=h, json={"lag_s": 1.0})
    assert r.json()["lag_s"] == 1.0
    bad = client.post("/api/v1/machines", headers=h, json={**MACHINE, "width_m": -1})
    assert bad.status_code == 422 and "width_m" in bad.json()["detail"]
    bad = client.post(
        "/api/v1/machines",
        headers=h,
        json={**MACHINE, "calibration": {"kind": "table", "rpm": [1]}},
    )
    assert bad.status_code == 422 and "calibration" in bad.json()["detail"]
    bad = client.post(
        "/api/v1/machines", headers=h, json={**MACHINE, "speed_min_m_s": 3, "speed_max_m_s": 2}
    )
    assert bad.status_code == 422
    assert client.get("/api/v1/machines", headers=h).json()["total"] == 1


def test_device_token_reads_only_own_machine(client, org) -> None:
    h = org.headers()
    m1 = client.post("/api/v1/machines", headers=h, json=MACHINE).json()
    m2 = client.post("/api/v1/machines", headers=h, json={**MACHINE, "name": "T2"}).json()
    tok = client.post(f"/api/v1/machines/{m1['id']}/device-token", headers=h).json()["token"]
    dh = {"Authorization": f"Bearer {tok}"}
    assert client.get(f"/api/v1/machines/{m1['id']}", headers=dh).status_code == 200
    assert client.get(f"/api/v1/machines/{m2['id']}", headers=dh).status_code == 404
    assert client.get("/api/v1/machines", headers=dh).status_code == 403
    assert client.get("/api/v1/fields", headers=dh).status_code == 403
    assert client.post("/api/v1/farms", headers=dh, json={"name": "x"}).status_code == 403
    # a new token revokes the old one
    client.post(f"/api/v1/machines/{m1['id']}/device-token", headers=h)
    assert client.get(f"/api/v1/machines/{m1['id']}", headers=dh).status_code == 401


def test_ids_beyond_the_database_range_are_bad_input_not_500(client, org) -> None:
    h = org.headers()
    for path in ("/api/v1/farms/10000000000000000001", "/api/v1/farms?offset=10000000000000000001"):
        r = client.get(path, headers=h)
        assert r.status_code == 422, (path, r.text)
        assert "out of range" in r.json()["detail"]
