"""Exports and job reports as background tasks.

In-process (``tasks.work.execute``, what a worker runs per job): a report task's snapshot
answers the report afterwards, asking again joins the open task, large jobs go to the queue
on their own. With a real ``fieldrx worker`` process: as-applied CSV and Shapefile and a
prescription export run as tasks with progress, the download streams the same bytes the
inline export answers with their media type, and the file is deleted after its retention
(the download then answers 410).
"""

from __future__ import annotations

import io
import zipfile
from typing import Any

import pytest
from sqlalchemy import text

from tests.fleet.helpers import make_job, record
from tests.tasks.helpers import wait_until
from tests.tasks.test_queue_workers import Worker

T0 = 1_790_000_000.0


@pytest.fixture()
def driven(client, org):  # noqa: ANN001, ANN201
    """A running job with 60 records over two cells."""
    fx = make_job(org.id, state="running", lag_s=0.0)
    recs = [record(fx, s, t=T0 + s * 0.1, cell=0) for s in range(1, 31)]
    recs += [record(fx, s, t=T0 + 13 + s * 0.1, cell=1) for s in range(31, 61)]
    r = client.post("/api/v1/telemetry", json={"records": recs}, headers=fx.device_headers)
    assert r.json()["acked_seq"] == 60
    return fx


@pytest.fixture(autouse=True)
def _fresh_settings():  # noqa: ANN202
    """Settings changed by a test (environment) do not outlive it."""
    from fieldrx.settings import get_settings

    yield
    get_settings.cache_clear()


def _settings(monkeypatch: pytest.MonkeyPatch, **env: str) -> None:
    from fieldrx.settings import get_settings

    for k, v in env.items():
        monkeypatch.setenv(k, v)
    get_settings.cache_clear()


def _clear_report_cache() -> None:
    """Forget this process's cached reports (another API process would not have them)."""
    from fieldrx.fleet.reports import clear_cache

    clear_cache()


def test_report_task_snapshot_answers_the_report(client, org, driven, db) -> None:  # noqa: ANN001
    from fieldrx.tasks.work import execute

    url = f"/api/v1/jobs/{driven.job_id}/report"
    inline = client.get(url, headers=org.headers(), params={"background": "false"}).json()
    _clear_report_cache()
    r = client.get(url, headers=org.headers(), params={"background": "true", "cells": "false"})
    assert r.status_code == 202, r.text
    task = r.json()
    assert task["kind"] == "report" and task["status"] == "queued"
    again = client.get(url, headers=org.headers(), params={"background": "true"})
    assert again.status_code == 202 and again.json()["id"] == task["id"]  # joins, no new task

    result = execute(task["id"])
    assert result is not None and result["job_id"] == driven.job_id and result["n_records"] == 60
    view = client.get(task["url"], headers=org.headers()).json()
    assert view["status"] == "succeeded" and view["result_url"] == url

    # a process without the report in memory answers from the task's snapshot
    _clear_report_cache()
    from fieldrx.fleet import reports

    built: list[int] = []
    real = reports.build_report

    def counting(*a: Any, **kw: Any) -> Any:
        built.append(1)
        return real(*a, **kw)

    reports.build_report = counting  # type: ignore[assignment]
    try:
        got = client.get(url, headers=org.headers(), params={"background": "true"})
    finally:
        reports.build_report = real  # type: ignore[assignment]
    assert got.status_code == 200 and built == []
    assert got.json() == inline

    # new records change the report's key: the snapshot no longer applies
    more = [record(driven, s, t=T0 + 30 + s * 0.1, cell=2) for s in range(61, 71)]
    client.post("/api/v1/telemetry", json={"records": more}, headers=driven.device_headers)
    _clear_report_cache()
    r2 = client.get(url, headers=org.headers(), params={"background": "true"})
    assert r2.status_code == 202 and r2.json()["id"] != task["id"]


def test_large_jobs_go_to_the_queue_on_their_own(client, org, driven, monkeypatch) -> None:  # noqa: ANN001
    _settings(monkeypatch, FIELDRX_REPORT_BACKGROUND_RECORDS="10")
    _clear_report_cache()
    h = org.headers()
    r = client.get(f"/api/v1/jobs/{driven.job_id}/report", headers=h)
    assert r.status_code == 202 and r.json()["kind"] == "report"
    e = client.get(f"/api/v1/jobs/{driven.job_id}/export", headers=h, params={"format": "csv"})
    assert e.status_code == 202 and e.json()["kind"] == "export"
    assert e.json()["params"] == {"source": "job", "job_id": driven.job_id, "format": "csv"}
    # inline on request, whatever the size
    assert (
        client.get(
            f"/api/v1/jobs/{driven.job_id}/report", headers=h, params={"background": "false"}
        ).status_code
        == 200
    )
    _settings(monkeypatch, FIELDRX_REPORT_BACKGROUND_RECORDS="1000")
    assert client.get(f"/api/v1/jobs/{driven.job_id}/report", headers=h).status_code == 200


def test_download_states_cancel_and_tenancy(client, org, make_org, driven) -> None:  # noqa: ANN001
    from fieldrx.tasks.work import execute

    h = org.headers()
    task = client.get(
        f"/api/v1/jobs/{driven.job_id}/export",
        headers=h,
        params={"format": "csv", "background": "true"},
    ).json()
    dl = f"/api/v1/tasks/{task['id']}/download"
    r = client.get(dl, headers=h)
    assert r.status_code == 409 and "queued" in r.json()["detail"]
    other = make_org()
    assert client.get(dl, headers=other.headers()).status_code == 404
    c = client.post(f"/api/v1/tasks/{task['id']}/cancel", headers=h).json()
    assert c["status"] == "cancelled" and c["cancelled"] == 1
    assert execute(task["id"]) is None  # a cancelled export never runs
    assert client.get(dl, headers=h).status_code == 409

    plan_task = client.get(
        f"/api/v1/jobs/{driven.job_id}/export", headers=h, params={"background": "true"}
    ).json()
    assert execute(plan_task["id"])["size"] > 0
    assert execute(plan_task["id"]) is None  # a second run stores nothing more
    assert client.get(f"/api/v1/tasks/{plan_task['id']}/download", headers=h).status_code == 200


def test_jobs_list_names_machine_field_product_and_dates(client, org, driven, db) -> None:  # noqa: ANN001
    db.execute(
        text("UPDATE prescriptions SET product = 'urea 46 %' WHERE id = :id"),
        {"id": driven.prescription_id},
    )
    db.execute(
        text(
            "INSERT INTO job_events (machine_id, job_id, state, note)"
            " VALUES (:m, :j, 'running', '')"
        ),
        {"m": driven.machine_id, "j": driven.job_id},
    )
    db.commit()
    items = client.get("/api/v1/jobs", headers=org.headers("viewer")).json()["items"]
    (j,) = [i for i in items if i["id"] == driven.job_id]
    assert j["machine_name"].startswith("tractor-") and j["field_name"] == "plot"
    assert j["field_id"] == driven.field_id and j["product"] == "urea 46 %"
    assert j["started_at"] is not None and j["ended_at"] is None
    one = client.get(f"/api/v1/jobs/{driven.job_id}", headers=org.headers()).json()
    assert one["product"] == "urea 46 %" and one["field_name"] == "plot"


@pytest.mark.timeout(300)
def test_exports_through_a_real_worker_download_and_retention(
    client, org, driven, database_url, tmp_path, monkeypatch
) -> None:  # noqa: ANN001
    h = org.headers()
    jurl = f"/api/v1/jobs/{driven.job_id}/export"
    rurl = f"/api/v1/prescriptions/{driven.prescription_id}/export"
    inline = {
        "csv": client.get(jurl, headers=h, params={"format": "csv", "background": "false"}),
        "geojson": client.get(rurl, headers=h, params={"format": "geojson", "background": "false"}),
    }
    queued = {
        "csv": client.get(jurl, headers=h, params={"format": "csv", "background": "true"}),
        "shapefile": client.get(
            jurl, headers=h, params={"format": "shapefile", "background": "true"}
        ),
        "geojson": client.get(rurl, headers=h, params={"format": "geojson", "background": "true"}),
    }
    assert all(r.status_code == 202 for r in queued.values()), [r.text for r in queued.values()]
    tasks = {k: r.json() for k, r in queued.items()}

    monkeypatch.setenv("FIELDRX_TASK_RESULT_RETENTION_S", "12")
    monkeypatch.setenv("FIELDRX_TASK_RESULT_PURGE_S", "0.5")
    w = Worker(database_url, tmp_path / "worker.log")
    try:

        def finished() -> dict[str, Any] | None:
            views = {k: client.get(t["url"], headers=h).json() for k, t in tasks.items()}
            done = all(v["status"] in ("succeeded", "failed", "cancelled") for v in views.values())
            return views if done else None

        views = wait_until(finished, 120, "the export tasks to finish", 0.1)
        assert all(v["status"] == "succeeded" for v in views.values()), views
        got = {k: client.get(v["result_url"], headers=h) for k, v in views.items()}
        for k, r in got.items():
            assert r.status_code == 200, (k, r.text)
            assert views[k]["result_url"] == f"/api/v1/tasks/{tasks[k]['id']}/download"
            assert views[k]["result"]["size"] == len(r.content)
            assert r.headers["content-disposition"].startswith("attachment; filename=")
        assert got["csv"].headers["content-type"].startswith("text/csv")
        assert got["csv"].content == inline["csv"].content
        assert got["geojson"].headers["content-type"].startswith("application/geo+json")
        assert got["geojson"].json() == inline["geojson"].json()
        assert got["shapefile"].headers["content-type"] == "application/zip"
        names = zipfile.ZipFile(io.BytesIO(got["shapefile"].content)).namelist()
        assert any(n.endswith(".shp") for n in names), names

        # after the retention the worker deletes the files; the download says so
        dl = views["csv"]["result_url"]
        wait_until(lambda: client.get(dl, headers=h).status_code == 410, 60, "the purge", 0.5)
        assert "retention" in client.get(dl, headers=h).json()["detail"]
    finally:
        rc = w.stop()
    assert rc == 0, w.log.read_text()[-3000:]


@pytest.mark.timeout(600)
def test_cancel_of_a_running_report_stops_it_within_seconds(
    client, org, driven, db, database_url, tmp_path
) -> None:  # noqa: ANN001
    """A job report over a million records runs in a real ``fieldrx worker``; its long
    stages report no progress, and the cancel used to wait for the next stage (19 s): the
    task now stops within a couple of seconds and stores nothing."""
    import time

    n = 1_000_000
    db.execute(
        text(
            "INSERT INTO telemetry (machine_id, seq, t, job_id, geom, fix_quality, cell_seq,"
            " target_rate_kg_ha, applied_rate_kg_ha, implement_down, alarms, queue_backlog,"
            " speed_raw_m_s, speed_filtered_m_s)"
            " SELECT :m, 100 + g, to_timestamp(:t0 + 20 + g * 0.01), :j,"
            " ST_SetSRID(ST_MakePoint(8.5 + (g % 1000) * 1e-6, 47.3 + (g / 1000) * 1e-7), 4326),"
            " 4, g % 2, 120, 118, true, '{}', 0, 2.0, 2.0 FROM generate_series(1, :n) g"
        ),
        {"m": driven.machine_id, "j": driven.job_id, "t0": T0, "n": n},
    )
    db.execute(
        text(
            "UPDATE telemetry_job_spans SET last_t = to_timestamp(:t1), n_records = n_records + :n"
            " WHERE machine_id = :m AND job_id = :j"
        ),
        {"m": driven.machine_id, "j": driven.job_id, "t1": T0 + 20 + n * 0.01, "n": n},
    )
    db.commit()
    url = f"/api/v1/jobs/{driven.job_id}/report"
    task = client.get(url, headers=org.headers(), params={"background": "true"}).json()
    assert task["kind"] == "report", task
    w = Worker(database_url, tmp_path / "worker.log")
    try:
        wait_until(
            lambda: client.get(task["url"], headers=org.headers()).json()["progress"] > 0,
            300,
            "the report to report progress in the worker",
            step_s=0.05,
        )
        t0 = time.monotonic()
        r = client.post(f"{task['url']}/cancel", headers=org.headers())
        assert r.status_code == 202 and r.json()["stopping"] == 1, r.text
        got = wait_until(
            lambda: (v := client.get(task["url"], headers=org.headers()).json())["status"]
            != "running"
            and v,
            120,
            "the task to stop",
            step_s=0.05,
        )
        stopped_s = time.monotonic() - t0
    finally:
        w.stop()
    print(f"report cancelled after {stopped_s:.2f} s")
    assert got["status"] == "cancelled", (got, w.log.read_text()[-3000:])
    assert stopped_s < 3.0, (stopped_s, w.log.read_text()[-3000:])
