"""Evidence is never erased silently: deletes that would erase as-applied data answer 409
naming the jobs; archiving a job keeps its as-applied records after the delete."""

from __future__ import annotations

import pytest

from tests.fleet.helpers import JobFixture, make_job, record

API = "/api/v1"


def _applied(client, fx: JobFixture) -> None:  # noqa: ANN001
    recs = [record(fx, i, cell=i % 8) for i in range(1, 17)]
    r = client.post(f"{API}/telemetry", json={"records": recs}, headers=fx.device_headers)
    assert r.status_code < 300, r.text


def _targets(fx: JobFixture) -> list[str]:
    return [
        f"{API}/machines/{fx.machine_id}",
        f"{API}/fields/{fx.field_id}",
        f"{API}/plans/{fx.plan_id}",
        f"{API}/prescriptions/{fx.prescription_id}",
    ]


@pytest.mark.parametrize("which", [0, 1, 2, 3], ids=["machine", "field", "plan", "prescription"])
def test_delete_with_as_applied_data_is_409_naming_the_jobs(client, org, db, which) -> None:  # noqa: ANN001
    from sqlalchemy import text

    fx = make_job(org.id, state="running")
    _applied(client, fx)
    h = org.headers()
    r = client.delete(_targets(fx)[which], headers=h)
    assert r.status_code == 409, r.text
    assert r.json()["jobs"] == [fx.job_id]
    assert f"job(s) {fx.job_id}" in r.json()["detail"]
    assert "archive" in r.json()["detail"]
    n = db.scalar(text("SELECT count(*) FROM telemetry WHERE job_id = :j"), {"j": fx.job_id})
    assert n == 16
    assert client.get(f"{API}/jobs/{fx.job_id}", headers=h).status_code == 200


def test_delete_without_as_applied_data_still_works(client, org) -> None:  # noqa: ANN001
    fx = make_job(org.id, state="planned")
    r = client.delete(f"{API}/machines/{fx.machine_id}", headers=org.headers())
    assert r.status_code == 204, r.text


def test_archived_job_evidence_outlives_the_machine(client, org) -> None:  # noqa: ANN001
    fx = make_job(org.id, state="running")
    _applied(client, fx)
    h = org.headers()
    before = client.get(f"{API}/jobs/{fx.job_id}/summary", headers=h).json()
    a = client.post(f"{API}/jobs/{fx.job_id}/archive", headers=h)
    assert a.status_code == 201, a.text
    assert client.delete(f"{API}/fields/{fx.field_id}", headers=h).status_code == 204
    assert client.delete(f"{API}/machines/{fx.machine_id}", headers=h).status_code == 204
    assert client.get(f"{API}/jobs/{fx.job_id}", headers=h).status_code == 404
    kept = client.get(f"{API}/job-archives/{fx.job_id}", headers=h)
    assert kept.status_code == 200, kept.text
    body = kept.json()
    assert body["summary"]["applied_total_kg"] == pytest.approx(before["applied_total_kg"])
    assert body["summary"]["cells_applied"] == before["cells_applied"] > 0
    assert len(body["cells"]["features"]) == before["cells_planned"]
    listed = client.get(f"{API}/job-archives", headers=h).json()
    assert [i["job_id"] for i in listed["items"]] == [fx.job_id]


def test_archive_of_another_organisation_is_404(client, org, make_org) -> None:  # noqa: ANN001
    fx = make_job(org.id, state="running")
    other = make_org()
    assert (
        client.post(f"{API}/jobs/{fx.job_id}/archive", headers=other.headers()).status_code == 404
    )
    assert client.get(f"{API}/job-archives/{fx.job_id}", headers=other.headers()).status_code == 404
