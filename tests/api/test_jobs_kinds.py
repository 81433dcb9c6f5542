"""Creating sensor-kind jobs through the API: defaults, what is refused (and that a
refusal leaves no job behind), tenancy, the device listing and the package."""

from __future__ import annotations

from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.ndvi import SEED000_TABLE

from tests.support import BOTH_KINDS, DEPTH_SEEDER, SMALL_PLOT, feature, machine_body


def _plan(client, org, width: float) -> tuple[int, int]:  # noqa: ANN001
    h = org.headers()
    f = client.post("/api/v1/fields", json=feature(SMALL_PLOT, name="api plot"), headers=h).json()
    body = machine_body("api kinds", width, calibration=SEED000_TABLE.to_dict(), **BOTH_KINDS)
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
    # the defaults: the machine's 2.3 m replaces seed 000's 3.6 m, and the history says so;
    # at 2.3 m the table meters no less than 285 kg/ha: the curve's low end needs confirming
    r = client.post("/api/v1/jobs", json=base, headers=h)
    assert r.status_code == 409 and r.json()["where"] == "confirm_flagged", r.text
    assert client.get("/api/v1/jobs", headers=h).json()["total"] == n_jobs
    r = client.post("/api/v1/jobs", json={**base, "confirm_flagged": True}, headers=h)
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


def test_job_refused_for_a_machine_that_cannot_do_it(client, org) -> None:  # noqa: ANN001
    """A disc spreader was given a seeding-depth and an NDVI job; both are refused with the
    reason (what the machine lacks), nothing is stored, and a machine that has what the kind
    needs gets the job. Sending re-checks the machine (its sensors may have gone)."""
    h = org.headers()
    plan_id, _ = _plan(client, org, 2.3)
    spreader = client.post(
        "/api/v1/machines",
        json=machine_body("disc spreader", 2.3, calibration=SEED000_TABLE.to_dict()),
        headers=h,
    ).json()
    assert spreader["implement_type"] == "spreader"
    assert spreader["capabilities"] == {"sections": 1, "depth_actuator": False, "sensors": []}
    n_jobs = client.get("/api/v1/jobs", headers=h).json()["total"]
    seed = {"kind": "seeding_depth", "plan_id": plan_id, "machine_id": spreader["id"]}
    r = client.post("/api/v1/jobs", json=seed, headers=h)
    assert r.status_code == 422 and r.json()["where"] == "machine_id", r.text
    d = r.json()["detail"]
    assert "implement type 'spreader' does not sow" in d and "no depth actuator" in d, d
    ndvi = {**seed, "kind": "ndvi_topdress"}
    r = client.post("/api/v1/jobs", json=ndvi, headers=h)
    assert r.status_code == 422 and r.json()["where"] == "machine_id", r.text
    assert "no canopy NDVI sensors" in r.json()["detail"]
    assert "does not apply fertiliser" not in r.json()["detail"]  # a spreader does
    assert client.get("/api/v1/jobs", headers=h).json()["total"] == n_jobs

    # the same spreader with canopy sensors may topdress
    r = client.patch(
        f"/api/v1/machines/{spreader['id']}",
        json={"capabilities": {"sensors": ["canopy_ndvi"]}},
        headers=h,
    )
    assert r.status_code == 200 and r.json()["capabilities"]["sensors"] == ["canopy_ndvi"]
    # (its meter cannot go as low as the curve: that is confirmed, not what is tested here)
    r = client.post("/api/v1/jobs", json={**ndvi, "confirm_flagged": True}, headers=h)
    assert r.status_code == 201, r.text
    job = r.json()
    # its sensors are removed before it is sent: sending is refused, the job stays planned
    client.patch(
        f"/api/v1/machines/{spreader['id']}", json={"capabilities": {"sensors": []}}, headers=h
    )
    r = client.post(f"/api/v1/jobs/{job['id']}/state", json={"state": "sent"}, headers=h)
    assert r.status_code == 422 and "no canopy NDVI sensors" in r.json()["detail"], r.text
    assert client.get(f"/api/v1/jobs/{job['id']}", headers=h).json()["state"] == "planned"

    # a seeder with a depth actuator and sensor gets the seeding job; a bad type is a 422
    seeder = client.post(
        "/api/v1/machines",
        json=machine_body("depth seeder", 2.3, calibration=SEED000_TABLE.to_dict(), **DEPTH_SEEDER),
        headers=h,
    ).json()
    r = client.post("/api/v1/jobs", json={**seed, "machine_id": seeder["id"]}, headers=h)
    assert r.status_code == 201, r.text
    bad = client.post(
        "/api/v1/machines", json=machine_body("x", implement_type="plough"), headers=h
    )
    assert bad.status_code == 422 and "implement_type" in bad.text
