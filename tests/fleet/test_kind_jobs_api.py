"""Creating sensor-kind jobs through the API: defaults, what is refused (and that a
refusal leaves no job behind), tenancy, the device listing and the package."""

from __future__ import annotations

from fieldrx_edge.ndvi import SEED000_TABLE
from fieldrx_edge.protocol import JobPackage

from tests.support import SMALL_PLOT, feature, machine_body


def _plan(client, org, width: float) -> tuple[int, int]:  # noqa: ANN001
    h = org.headers()
    f = client.post("/api/v1/fields", json=feature(SMALL_PLOT, name="api plot"), headers=h).json()
    body = machine_body("api kinds", width, calibration=SEED000_TABLE.to_dict())
    m = client.post("/api/v1/machines", json=body, headers=h).json()
    p = client.post(
        f"/api/v1/fields/{f['id']}/plans",
        json={"swath_width_m": width, "cell_length_m": 5.0},
        headers=h,
    )
    assert p.status_code == 201, p.text
    return p.json()["id"], m["id"]


def test_kind_job_validation_and_defaults(client, org, make_org) -> None:  # noqa: ANN001
    h = org.headers()
    plan_id, machine_id = _plan(client, org, 2.3)
    n_jobs = client.get("/api/v1/jobs", headers=h).json()["total"]
    base = {"kind": "ndvi_topdress", "plan_id": plan_id, "machine_id": machine_id}
    cases = [
        ({**base, "settings": {"window": -1}}, 422, "settings.window"),
        ({**base, "settings": {"sensors": {"height_m": 9}}}, 422, "settings.sensors.height_m"),
        ({**base, "settings": {"implement_width_m": 3.6}}, 422, "settings.implement_width_m"),
        ({**base, "prescription_id": 1}, 422, "prescription_id"),
        ({k: v for k, v in base.items() if k != "plan_id"}, 422, "plan_id"),
        ({**base, "plan_id": 10**6}, 404, "plan_id"),
        ({**base, "kind": "seeding_depth", "settings": {"target_depth_mm": 0}}, 422,
         "settings.target_depth_mm"),
        ({"plan_id": plan_id, "machine_id": machine_id}, 422, "prescription_id"),
    ]  # fmt: skip
    for body, status, where in cases:
        r = client.post("/api/v1/jobs", json=body, headers=h)
        assert r.status_code == status, (body, r.text)
        assert r.json()["where"] == where, (body, r.json())
    assert client.get("/api/v1/jobs", headers=h).json()["total"] == n_jobs  # nothing left behind
    # another organisation cannot drive this plan
    other = make_org()
    _, other_machine = _plan(client, other, 2.3)
    r = client.post(
        "/api/v1/jobs", json={**base, "machine_id": other_machine}, headers=other.headers()
    )
    assert r.status_code == 404 and r.json()["where"] == "plan_id"
    # the defaults: the machine's 2.3 m replaces seed 000's 3.6 m, and the history says so
    r = client.post("/api/v1/jobs", json=base, headers=h)
    assert r.status_code == 201, r.text
    job = r.json()
    assert job["settings"]["implement_width_m"] == 2.3
    assert "seed 000's default is 3.6 m" in job["events"][0]["note"]
    assert job["n_cells"] > 0 and job["kind"] == "ndvi_topdress"
    kinds = client.get("/api/v1/jobs/kinds", headers=h).json()["kinds"]
    assert kinds["seeding_depth"]["defaults"]["target_depth_mm"] == 30.0
    assert kinds["seeding_depth"]["controllers"] == ["fuzzy_pid", "pid"]
    # the device lists it and downloads a package that carries the kind and its settings
    tok = client.post(f"/api/v1/machines/{machine_id}/device-token", headers=h).json()["token"]
    assert client.post(f"/api/v1/jobs/{job['id']}/state", json={"state": "sent"}, headers=h)
    dev = {"Authorization": f"Bearer {tok}"}
    listed = client.get("/api/v1/device/jobs", headers=dev).json()["items"]
    assert [j["id"] for j in listed] == [job["id"]] and listed[0]["kind"] == "ndvi_topdress"
    pkg = JobPackage.from_json(client.get(f"/api/v1/device/jobs/{job['id']}/package",
                                          headers=dev).content)  # fmt: skip
    assert pkg.kind == "ndvi_topdress" and pkg.kind_settings == job["settings"]
    assert pkg.n_cells == job["n_cells"] and set(pkg.rate_kg_ha) == {0.0}
    # seed 001's per-cell as-applied views point to the kind's own report (no 500)
    for path in ("summary", "as-applied/cells", "export"):
        r = client.get(f"/api/v1/jobs/{job['id']}/{path}", headers=h)
        assert r.status_code == 409 and f"/jobs/{job['id']}/report" in r.json()["detail"], path
    r = client.get(f"/api/v1/jobs/{job['id']}/report", headers=h)
    assert r.status_code == 200 and r.json()["n_records"] == 0 and r.json()["cells"] == []
