"""ISOXML import: preview then confirm, round trip of FieldRx's own exports."""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest

from tests.support.plans import API, make_field, make_plan
from tests.support.prescriptions import FIELD, all_cells, make_rx, samples_csv


def holed_field() -> dict:
    ring = FIELD["coordinates"][0]
    (lon0, lat0), (lon1, lat1) = ring[0], ring[2]
    cx, cy, dx, dy = (lon0 + lon1) / 2, (lat0 + lat1) / 2, (lon1 - lon0) / 8, (lat1 - lat0) / 8
    hole = [
        [cx - dx, cy - dy],
        [cx - dx, cy + dy],
        [cx + dx, cy + dy],
        [cx + dx, cy - dy],
        [cx - dx, cy - dy],
    ]
    return {"type": "Polygon", "coordinates": [ring, hole]}


@pytest.fixture()
def rx(client, org):
    h = org.headers()
    fid = make_field(client, h, holed_field(), name="Pond field")
    r = client.post(
        f"{API}/fields/{fid}/soil-samples",
        headers=h,
        files={"file": ("s.csv", samples_csv(grid=4), "text/csv")},
    )
    assert r.status_code == 201, r.text
    plan = make_plan(client, h, fid, swath_width_m=4, cell_length_m=5)
    r = make_rx(
        client,
        h,
        plan["id"],
        name="N spring",
        model="nutrient_balance",
        params={"target_yield_kg_ha": 2500, "n_fraction": 0.25},
        interpolation="idw",
    )
    field = client.get(f"{API}/fields/{fid}", headers=h).json()
    return {"id": r["id"], "h": h, "field": field, "cells": all_cells(client, h, r["id"])}


def _count(client, h, what):
    return client.get(f"{API}/{what}", headers=h).json()["total"]


def _import(client, h, data: bytes, name="TASKDATA.zip", **q):
    files = {"files": (name, data, "application/zip")}
    qs = "&".join(f"{k}={v}" for k, v in q.items())
    return client.post(f"{API}/imports/isoxml?{qs}", headers=h, files=files)


@pytest.mark.parametrize("fmt", ["isoxml", "isoxml-zones"])
def test_own_export_round_trips(client, rx, fmt):
    h = rx["h"]
    exp = client.get(f"{API}/prescriptions/{rx['id']}/export?format={fmt}", headers=h)
    assert exp.status_code == 200
    n_fields = _count(client, h, "fields")
    pre = _import(client, h, exp.content, swath_width_m=4, cell_length_m=5)
    assert pre.status_code == 200, pre.text
    body = pre.json()
    assert body["stored"] is False and _count(client, h, "fields") == n_fields  # nothing stored
    (f,) = body["preview"]["fields"]
    assert f["holes"] == 1
    # the exported field is this organisation's own: matched, never created again
    assert f["match"]["id"] == rx["field"]["id"] and "same boundary" in f["match"]["by"]
    a0 = rx["field"]["properties"]["area_m2"]
    assert f["area_m2"] == pytest.approx(a0, rel=1e-4)  # within 0.01 %
    (p,) = body["preview"]["prescriptions"]
    assert p["unit"] == "kg/ha" and p["ddi"] == 6
    assert p["kind"] == ("grid type 2" if fmt == "isoxml" else "zones")
    bad = _import(client, h, exp.content, confirm="0" * 64)
    assert bad.status_code == 409 and _count(client, h, "fields") == n_fields
    ok = _import(client, h, exp.content, confirm=body["sha256"], swath_width_m=4, cell_length_m=5)
    assert ok.status_code == 201, ok.text
    created = ok.json()["created"]
    assert created["fields"] == [] and _count(client, h, "fields") == n_fields
    assert [m["id"] for m in created["matched_fields"]] == [rx["field"]["id"]]
    new_rx = created["prescriptions"][0]["id"]
    got = {
        c["properties"]["seq"]: c["properties"]["rate_kg_ha"] for c in all_cells(client, h, new_rx)
    }
    want = {c["properties"]["seq"]: c["properties"]["rate_kg_ha"] for c in rx["cells"]}
    assert set(got) == set(want)  # same plan parameters on the same boundary: the same cells
    diff = np.array([abs(got[s] - want[s]) for s in want])
    if fmt == "isoxml":
        # the same rate per cell (0.01 kg/ha resolution); cells smaller than a few grid cells
        # may take the rate of the neighbour under most of their grid centres
        area = np.array([c["properties"]["area_m2"] for c in rx["cells"]])
        off = diff > 0.005
        few_grid_cells = np.median(area)  # 4 grid cells: the default grid cell is half a side
        assert off.mean() < 0.02 and (area[off] < few_grid_cells).all(), (off.sum(), area[off])
    else:
        zones = json.loads(exp.headers["X-FieldRx-Zones"])
        assert diff.max() <= zones["max_rate_change_kg_ha"] + 0.01  # the zone's rate per cell
    info = client.get(f"{API}/prescriptions/{new_rx}", headers=h).json()
    assert info["model"] == "imported"


def test_taskdata_zip_to_field_import_points_to_isoxml(client, rx):
    exp = client.get(f"{API}/prescriptions/{rx['id']}/export?format=isoxml", headers=rx["h"])
    r = client.post(
        f"{API}/fields/import",
        headers=rx["h"],
        files={"file": ("TASKDATA.zip", exp.content, "application/zip")},
    )
    assert r.status_code == 422
    assert "/api/v1/imports/isoxml" in r.json()["detail"]
    assert "exactly one .shp" not in r.json()["detail"]


def test_loose_files_accepted(client, rx):
    exp = client.get(f"{API}/prescriptions/{rx['id']}/export?format=isoxml", headers=rx["h"])
    z = zipfile.ZipFile(io.BytesIO(exp.content))
    files = [
        ("files", (n.split("/")[-1], z.read(n), "application/octet-stream")) for n in z.namelist()
    ]
    r = client.post(f"{API}/imports/isoxml", headers=rx["h"], files=files)
    assert r.status_code == 200, r.text
    assert r.json()["preview"]["prescriptions"][0]["kind"] == "grid type 2"


def _export_and_preview(client, rx):
    h = rx["h"]
    exp = client.get(f"{API}/prescriptions/{rx['id']}/export?format=isoxml", headers=h)
    assert exp.status_code == 200
    pre = _import(client, h, exp.content)
    assert pre.status_code == 200, pre.text
    return exp.content, pre.json()["sha256"]


def test_confirm_with_tiny_cells_is_refused_before_planning(client, rx):
    """The import confirm goes through the one cost estimate: a 2 mm swath with 1 mm cells
    used to plan ~20,000 swaths in the request thread for minutes before anything refused."""
    import threading
    import time

    h = rx["h"]
    data, sha = _export_and_preview(client, rx)
    n_fields = _count(client, h, "fields")
    out: dict = {}

    def confirm() -> None:
        t0 = time.monotonic()
        out["r"] = _import(client, h, data, confirm=sha, swath_width_m=0.002, cell_length_m=0.001)
        out["took"] = time.monotonic() - t0

    t = threading.Thread(target=confirm, daemon=True)
    t.start()
    t.join(60)
    assert not t.is_alive(), "the confirm was not refused within 60 s"
    r = out["r"]
    assert r.status_code == 422, r.text
    assert "cell_length_m must be >= 0.5" in r.json()["detail"]
    assert _count(client, h, "fields") == n_fields  # nothing stored


def test_confirm_plans_in_the_bounded_worker_with_the_plan_time_limit(
    client, rx, monkeypatch, database_url
):
    """Planning of an import confirm runs in a worker process under FIELDRX_PLAN_TIME_LIMIT_S
    (it ran in the request thread without any limit); past it: 422, nothing stored, and no
    session of the request is left idle in a transaction."""
    from fieldrx.settings import get_settings
    from sqlalchemy import create_engine, text

    h = rx["h"]
    data, sha = _export_and_preview(client, rx)
    n_fields = _count(client, h, "fields")
    monkeypatch.setattr(get_settings(), "plan_time_limit_s", 0.05)
    r = _import(client, h, data, confirm=sha, swath_width_m=1, cell_length_m=0.5)
    assert r.status_code == 422, r.text
    assert "longer than the 0.05 s limit" in r.json()["detail"]
    assert _count(client, h, "fields") == n_fields
    eng = create_engine(database_url)
    try:
        with eng.connect() as c:
            idle = c.execute(
                text(
                    "SELECT count(*) FROM pg_stat_activity WHERE datname = current_database() "
                    "AND state = 'idle in transaction'"
                )
            ).scalar()
    finally:
        eng.dispose()
    assert idle == 0


def _incoming(name: str):
    from fieldrx.tasks.context import incoming_upload

    return incoming_upload(name)


def test_confirm_runs_as_task_in_a_worker(client, rx, database_url, tmp_path, monkeypatch):
    """A confirm over FIELDRX_IMPORT_BACKGROUND_BYTES answers 202 with an ``import`` task;
    a real ``fieldrx worker`` stores the set, the task's result names what was created,
    and the spooled upload is kept until the task ran and removed after."""
    from fieldrx.settings import get_settings

    from tests.tasks.helpers import wait_until
    from tests.tasks.test_queue_workers import Worker

    h = rx["h"]
    data, sha = _export_and_preview(client, rx)
    n_rx = _count(client, h, "prescriptions")
    monkeypatch.setenv("FIELDRX_IMPORT_BACKGROUND_BYTES", str(len(data) - 1))
    get_settings.cache_clear()
    try:
        r = _import(client, h, data, confirm=sha, swath_width_m=4, cell_length_m=5)
    finally:
        monkeypatch.delenv("FIELDRX_IMPORT_BACKGROUND_BYTES")
        get_settings.cache_clear()
    assert r.status_code == 202, r.text
    task = r.json()
    assert task["kind"] == "import" and task["status"] == "queued"
    folder = _incoming(task["params"]["incoming"])
    assert sorted(p.name for p in folder.iterdir()) == ["0000.upload"]  # kept for the task
    assert _count(client, h, "prescriptions") == n_rx  # nothing stored before it ran

    w = Worker(database_url, tmp_path / "worker.log")
    try:

        def finished():
            v = client.get(task["url"], headers=h).json()
            return v if v["status"] in ("succeeded", "failed", "cancelled") else None

        view = wait_until(finished, 180, "the import task to finish", 0.2)
    finally:
        rc = w.stop()
    assert rc == 0, w.log.read_text()[-3000:]
    assert view["status"] == "succeeded", view
    assert view["progress"] == 1 and "1 prescription" in view["message"]
    created = view["result"]["created"]
    assert view["result"]["sha256"] == sha and view["result"]["skipped"] == []
    assert [m["id"] for m in created["matched_fields"]] == [rx["field"]["id"]]
    (new,) = created["prescriptions"]
    assert client.get(f"{API}/prescriptions/{new['id']}", headers=h).json()["model"] == "imported"
    assert _count(client, h, "prescriptions") == n_rx + 1
    assert not folder.exists()  # removed once the task ran


def test_failed_import_task_stores_nothing(client, rx, monkeypatch):
    """A task that runs out of its time limit while planning fails with the reason, stores
    no farm, field or prescription, and its spooled upload is removed."""
    from fieldrx.settings import get_settings
    from fieldrx.tasks.work import execute

    h = rx["h"]
    data, sha = _export_and_preview(client, rx)
    counts = {w: _count(client, h, w) for w in ("farms", "fields", "prescriptions")}
    r = _import(client, h, data, confirm=sha, background="true", swath_width_m=4, cell_length_m=5)
    assert r.status_code == 202, r.text
    task = r.json()
    folder = _incoming(task["params"]["incoming"])
    assert folder.is_dir()
    monkeypatch.setenv("FIELDRX_PLAN_TIME_LIMIT_S", "0.05")
    get_settings.cache_clear()
    try:
        out = execute(task["id"])
    finally:
        monkeypatch.delenv("FIELDRX_PLAN_TIME_LIMIT_S")
        get_settings.cache_clear()
    view = client.get(task["url"], headers=h).json()
    assert view["status"] == "failed" and out == {"error": view["error"]}, view
    assert "limit" in view["error"] and "nothing was stored" in view["error"]
    assert {w: _count(client, h, w) for w in counts} == counts
    assert not folder.exists()
