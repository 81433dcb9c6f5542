"""Jobs API, the state machine, device endpoints (package ETag/304/gzip) and tenancy."""

from __future__ import annotations

import gzip

import pytest
from fieldrx_edge.job_package import JobPackage

from tests.fleet.helpers import make_job
from tests.support import machine_body


def _state(client, org, job_id, state, role="agronomist"):  # noqa: ANN001, ANN202
    return client.post(
        f"/api/v1/jobs/{job_id}/state",
        json={"state": state, "note": "n"},
        headers=org.headers(role),
    )


def test_create_list_get(client, org) -> None:  # noqa: ANN001
    fx = make_job(org.id)
    body = {"prescription_id": fx.prescription_id, "machine_id": fx.machine_id}
    # the fixture's rates lie outside the machine's meter range: sending asks to confirm
    assert client.post("/api/v1/jobs", json=body, headers=org.headers()).status_code == 409
    r = client.post("/api/v1/jobs", json={**body, "confirm_flagged": True}, headers=org.headers())
    assert r.status_code == 201, r.text
    job = r.json()
    assert job["flagged_cells"] == 8 and job["flagged_confirmed"] is True
    assert job["state"] == "planned" and job["n_cells"] == 8 and job["prescription_version"] == 1
    assert job["events"][0]["state"] == "planned"
    assert job["events"][0]["by_user_id"] == org.user_ids["agronomist"]
    r = client.post(
        "/api/v1/jobs",
        json={
            "prescription_id": fx.prescription_id,
            "machine_id": fx.machine_id,
            "prescription_version": 7,
        },
        headers=org.headers(),
    )
    assert r.status_code == 404 and "version 7" in r.json()["detail"]
    lst = client.get("/api/v1/jobs?state=planned", headers=org.headers("viewer")).json()
    assert {j["id"] for j in lst["items"]} == {fx.job_id, job["id"]}
    assert client.get("/api/v1/jobs?state=running", headers=org.headers()).json()["total"] == 0
    assert client.get(f"/api/v1/jobs/{job['id']}", headers=org.headers()).json()["id"] == job["id"]
    assert _state(client, org, job["id"], "sent", role="viewer").status_code == 403


def test_state_machine(client, org) -> None:  # noqa: ANN001
    fx = make_job(org.id)
    path = ["sent", "downloaded", "running", "paused", "running", "completed"]
    for s in path:
        r = _state(client, org, fx.job_id, s)
        assert r.status_code == 200, r.text
        assert r.json()["state"] == s
    events = r.json()["events"]
    assert [e["state"] for e in events] == path  # the fixture job has no creation event
    assert all(e["at"] for e in events)
    r = _state(client, org, fx.job_id, "running")
    assert r.status_code == 409 and "final" in r.json()["detail"]
    assert _state(client, org, fx.job_id, "aborted").status_code == 409


@pytest.mark.parametrize(
    ("start", "bad"),
    [("planned", "running"), ("sent", "completed"), ("downloaded", "paused"), ("paused", "sent")],
)
def test_invalid_transitions(client, org, start, bad) -> None:  # noqa: ANN001
    fx = make_job(org.id, state=start)
    r = _state(client, org, fx.job_id, bad)
    assert r.status_code == 409
    assert f"from '{start}' to '{bad}'" in r.json()["detail"]
    assert _state(client, org, fx.job_id, "aborted").json()["state"] == "aborted"


def test_device_jobs_package_and_state(client, org) -> None:  # noqa: ANN001
    fx = make_job(org.id)
    dev = fx.device_headers
    assert client.get("/api/v1/device/jobs", headers=dev).json()["total"] == 0  # planned
    assert client.get(f"/api/v1/device/jobs/{fx.job_id}/package", headers=dev).status_code == 409
    _state(client, org, fx.job_id, "sent")
    items = client.get("/api/v1/device/jobs", headers=dev).json()["items"]
    assert [j["id"] for j in items] == [fx.job_id]
    r = client.get(f"/api/v1/device/jobs/{fx.job_id}/package", headers=dev)
    assert r.status_code == 200
    pkg = JobPackage.from_json(r.content)  # verifies the checksum
    assert r.headers["etag"] == f'"{pkg.checksum}"'
    assert pkg.seq == list(range(8)) and pkg.rate_kg_ha[0] == 300.0 and pkg.utm_epsg == 32649
    assert pkg.machine_id == fx.machine_id and pkg.job_id == fx.job_id
    job = client.get(f"/api/v1/jobs/{fx.job_id}", headers=org.headers()).json()
    assert job["state"] == "downloaded" and job["package_checksum"] == pkg.checksum
    assert job["events"][-1]["by_machine_id"] == fx.machine_id
    r = client.get(
        f"/api/v1/device/jobs/{fx.job_id}/package",
        headers={**dev, "If-None-Match": r.headers["etag"]},
    )
    assert r.status_code == 304 and not r.content
    raw = client.get(
        f"/api/v1/device/jobs/{fx.job_id}/package",
        headers={**dev, "Accept-Encoding": "gzip"},
    )
    assert raw.headers.get("content-encoding") == "gzip"
    assert JobPackage.from_json(raw.content).checksum == pkg.checksum  # httpx decodes gzip
    assert len(gzip.compress(raw.content)) > 0
    for s in ("running", "running", "paused", "running", "completed"):
        r = client.post(f"/api/v1/device/jobs/{fx.job_id}/state", json={"state": s}, headers=dev)
        assert r.status_code == 200, r.text
    r = client.post(
        f"/api/v1/device/jobs/{fx.job_id}/state", json={"state": "running"}, headers=dev
    )
    assert r.status_code == 409
    r = client.post(
        f"/api/v1/device/jobs/{fx.job_id}/state", json={"state": "aborted"}, headers=dev
    )
    assert r.status_code == 422


def test_isolation(client, make_org) -> None:  # noqa: ANN001
    a, b = make_org(), make_org()
    fa, fb = make_job(a.id, state="sent"), make_job(b.id, state="sent")
    fa2 = make_job(a.id, state="sent")
    # users of another organisation
    assert client.get(f"/api/v1/jobs/{fa.job_id}", headers=b.headers()).status_code == 404
    assert _state(client, b, fa.job_id, "aborted").status_code == 404
    assert fa.job_id not in {
        j["id"] for j in client.get("/api/v1/jobs", headers=b.headers()).json()["items"]
    }
    r = client.post(
        "/api/v1/jobs",
        json={"prescription_id": fa.prescription_id, "machine_id": fb.machine_id},
        headers=b.headers(),
    )
    assert r.status_code == 404
    # a device token: not another organisation's job, not another machine's job, not user APIs
    for other in (fb.job_id, fa2.job_id):
        assert (
            client.get(
                f"/api/v1/device/jobs/{other}/package", headers=fa.device_headers
            ).status_code
            == 404
        )
        r = client.post(
            f"/api/v1/device/jobs/{other}/state",
            json={"state": "running"},
            headers=fa.device_headers,
        )
        assert r.status_code == 404
    assert client.get(f"/api/v1/jobs/{fa.job_id}", headers=fa.device_headers).status_code == 403
    assert client.get("/api/v1/device/jobs", headers=a.headers()).status_code == 403


def test_machine_width_must_match_the_plan(client, org) -> None:  # noqa: ANN001
    fx = make_job(org.id)
    wide = client.post(
        "/api/v1/machines", headers=org.headers(), json=machine_body("12 m spreader", 12.0)
    ).json()
    r = client.post(
        "/api/v1/jobs",
        json={"prescription_id": fx.prescription_id, "machine_id": wide["id"]},
        headers=org.headers(),
    )
    assert r.status_code == 422, r.text
    assert "works 12 m wide" in r.json()["detail"] and r.json()["where"] == "machine_id"
    assert client.get("/api/v1/jobs", headers=org.headers()).json()["total"] == 1  # only fx's
