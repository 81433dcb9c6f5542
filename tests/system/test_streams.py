"""Telemetry streams and fix-time records, end to end.

* defect 1: a machine whose agent queue starts over (no --state-dir, a wiped
  queue, a second tablet with the same device token, a restored copy) loses
  nothing: records are keyed by (machine, stream, seq), a seq is a duplicate
  only when it holds the same record, and nothing is acknowledged unstored;
* defect 2: a paced simulation (records 0.1 s apart in fix time, sent 0.1 /
  realtime s apart) reports the same as an unpaced one.

A real API server process (uvicorn), real PostGIS, the real `fieldrx-edge` CLI.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from fieldrx_edge.protocol import mqtt_username
from fieldrx_edge.uplink import Backoff, HttpSender, MqttBroker, MqttSender, TelemetryQueue
from sqlalchemy import text

from tests.fleet.helpers import JobFixture, make_job, record
from tests.fleet.procs import BIN, ROOT, start_api, start_worker
from tests.mqtt_broker import mqtt_port
from tests.support import SEED001_CAL, SMALL_PLOT, feature, machine_body, scaled


@pytest.fixture(scope="module")
def api_url(database_url: str) -> Iterator[str]:
    api, url = start_api(database_url)
    try:
        yield url
    finally:
        api.stop()


def _plan_jobs(c: httpx.Client, n_jobs: int) -> tuple[str, list[int]]:
    """One machine, one planned small plot with a varying prescription, ``n_jobs`` jobs
    of it for that machine (sent). Returns the device token and the job ids."""
    field = c.post("/api/v1/fields", json=feature(SMALL_PLOT, name="plot")).json()
    # a 10 r/min shaft floor so the 220-340 kg/ha edits are meterable (as test_simulated_job)
    cal = {**SEED001_CAL, "min_rpm": 10.0}
    m = c.post("/api/v1/machines", json=machine_body("sim", 2.3, calibration=cal)).json()
    token = c.post(f"/api/v1/machines/{m['id']}/device-token").json()["token"]
    plan = c.post(
        f"/api/v1/fields/{field['id']}/plans", json={"swath_width_m": 2.3, "cell_length_m": 5.0}
    )
    assert plan.status_code == 201, plan.text
    plan = plan.json()
    rx = c.post(
        f"/api/v1/plans/{plan['id']}/prescriptions",
        json={"model": "uniform", "params": {"rate_kg_ha": 300.0}, "machine_id": m["id"]},
    )
    assert rx.status_code == 201, rx.text
    rx = rx.json()
    n = plan.get("n_cells") or len(
        c.get(f"/api/v1/plans/{plan['id']}/cells?limit=1000").json()["features"]
    )
    edits = [{"seq": s, "rate_kg_ha": 220.0 + 40.0 * (s % 4)} for s in range(n)]
    assert c.post(f"/api/v1/prescriptions/{rx['id']}/edits", json={"cells": edits}).is_success
    jobs = []
    for _ in range(n_jobs):
        job = c.post("/api/v1/jobs", json={"prescription_id": rx["id"], "machine_id": m["id"]})
        assert job.status_code == 201, job.text
        jid = job.json()["id"]
        assert c.post(f"/api/v1/jobs/{jid}/state", json={"state": "sent"}).status_code == 200
        jobs.append(jid)
    return token, jobs


def _simulate(url: str, token: str, job_id: int, tmp: Path, *extra: str) -> dict[str, Any]:
    """`fieldrx-edge simulate` of the server's package for ``job_id``, WITHOUT --state-dir
    (a fresh queue every run, as the issue reports) unless ``extra`` gives one."""
    pkg = httpx.get(
        f"{url}/api/v1/device/jobs/{job_id}/package",
        headers={"Authorization": f"Bearer {token}"},
    )
    assert pkg.status_code == 200, pkg.text
    path = tmp / f"job{job_id}.json"
    path.write_bytes(pkg.content)
    out = subprocess.run(
        [str(BIN / "fieldrx-edge"), "simulate", str(path), "--server", url, "--token", token,
         "--json", "--seed", "3", "--compare-runs", "1", *extra],
        cwd=ROOT, capture_output=True, text=True, timeout=scaled(300),
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_two_simulations_without_state_dir_store_both_jobs(
    api_url: str,
    org,
    db,
    tmp_path: Path,  # noqa: ANN001
) -> None:
    """(a): the second run's queue numbers from 1 again; it used to be
    acknowledged, stored nothing, and its job completed with 0 records."""
    c = httpx.Client(base_url=api_url, headers=org.headers(), timeout=scaled(60))
    token, (j1, j2) = _plan_jobs(c, 2)
    sims = [_simulate(api_url, token, j, tmp_path) for j in (j1, j2)]
    for sim in sims:
        assert sim["telemetry_drained"] is True
        assert sim["telemetry"]["rejected"] == 0
    reports = [c.get(f"/api/v1/jobs/{j}/report").json() for j in (j1, j2)]
    for sim, rep in zip(sims, reports, strict=True):
        assert rep["n_records"] == sim["telemetry"]["last_seq"] > 1000
        assert rep["applied_total_kg"] > 0.9 * sim["applied_total_kg"]
    # same seed, same package: the two jobs' reports agree
    assert reports[1]["applied_total_kg"] == pytest.approx(reports[0]["applied_total_kg"], 1e-6)
    assert c.get(f"/api/v1/jobs/{j2}").json()["state"] == "completed"
    assert sims[0]["telemetry"]["stream"] != sims[1]["telemetry"]["stream"]
    machine = c.get(f"/api/v1/jobs/{j2}").json()["machine_id"]
    streams = c.get(f"/api/v1/machines/{machine}/telemetry-streams").json()
    assert sorted(s["stream"] for s in streams) == sorted(s["telemetry"]["stream"] for s in sims)
    assert all(s["first_seq"] == 1 and s["acked_seq"] == s["n_records"] for s in streams)
    # one after the other is not two agents at once
    n_alerts = db.execute(
        text("SELECT count(*) FROM alerts WHERE machine_id = :m AND kind = 'duplicate_stream'"),
        {"m": machine},
    ).scalar()
    assert n_alerts == 0


def test_paced_and_unpaced_simulations_report_the_same(
    api_url: str,
    org,
    tmp_path: Path,  # noqa: ANN001
) -> None:
    """(b): paced, the simulator stamped wall-clock times 1/realtime of the
    GNSS period apart and the report integrated 1/realtime of the mass."""
    c = httpx.Client(base_url=api_url, headers=org.headers(), timeout=scaled(60))
    token, (j1, j2) = _plan_jobs(c, 2)
    # one state dir for both runs: this test is about time, not about streams
    state = ("--state-dir", str(tmp_path / "state"))
    fast = _simulate(api_url, token, j1, tmp_path, *state)
    t0 = time.monotonic()
    paced = _simulate(api_url, token, j2, tmp_path, "--realtime", "60", *state)
    assert time.monotonic() - t0 >= 0.9 * paced["driven_s"] / 60  # it really was paced
    assert paced["applied_total_kg"] == pytest.approx(fast["applied_total_kg"], rel=1e-9)
    r1, r2 = (c.get(f"/api/v1/jobs/{j}/report").json() for j in (j1, j2))
    for key in ("applied_total_kg", "applied_in_cells_kg", "mean_accuracy_pct", "time_worked_s"):
        assert r2[key] == pytest.approx(r1[key], rel=0.01), key
    # and both are the simulator's own figures (time worked: the drive, implement down)
    assert r1["applied_total_kg"] == pytest.approx(fast["applied_total_kg"], rel=0.01)
    assert abs(r2["mean_accuracy_pct"] - paced["mean_accuracy_pct"]) < 1.0
    assert r2["time_worked_s"] > 0.5 * paced["driven_s"]


def _sender(q: TelemetryQueue, url: str, fx: JobFixture) -> HttpSender:
    return HttpSender(q, url, fx.device_token, batch_size=40, backoff=Backoff(0.01, 0.05))


def _count(db, machine_id: int) -> int:  # noqa: ANN001
    return db.execute(
        text("SELECT count(*) FROM telemetry WHERE machine_id = :m"), {"m": machine_id}
    ).scalar_one()


def _stored(db, machine_id: int) -> list[tuple[str, int, float]]:  # noqa: ANN001
    return [
        tuple(r)
        for r in db.execute(
            text(
                "SELECT stream, seq, extract(epoch FROM t)::float8 FROM telemetry"
                " WHERE machine_id = :m ORDER BY t, stream, seq"
            ),
            {"m": machine_id},
        )
    ]


def test_queue_wiped_mid_job_loses_nothing(api_url: str, org, db, tmp_path: Path) -> None:  # noqa: ANN001
    fx = make_job(org.id, state="running")
    t0 = time.time() - 600
    q1 = TelemetryQueue(tmp_path / "a" / "queue.sqlite", fx.machine_id)
    q1.put_many([record(fx, 0, t=t0 + 0.1 * i, cell=i // 20) for i in range(60)])
    s1 = _sender(q1, api_url, fx)
    assert s1.drain(20)
    s1.close()
    sid1 = q1.stats().get("stream")
    q1.close()
    shutil.rmtree(tmp_path / "a")  # the state directory is gone mid-job
    q2 = TelemetryQueue(tmp_path / "a" / "queue.sqlite", fx.machine_id)
    assert q2.last_seq == 0
    q2.put_many([record(fx, 0, t=t0 + 6.0 + 0.1 * i, cell=3 + i // 20) for i in range(60)])
    s2 = _sender(q2, api_url, fx)
    assert s2.drain(20)
    s2.close()
    assert _count(db, fx.machine_id) == 120  # the old code acknowledged q2's 60 unstored
    assert q2.stream[0] != sid1
    rows = _stored(db, fx.machine_id)
    assert [r[1] for r in rows] == list(range(1, 61)) * 2
    assert {r[0] for r in rows[:60]} == {sid1} and {r[0] for r in rows[60:]} == {q2.stream[0]}
    assert q2.stats()["rejected"] == 0


def test_two_agents_with_one_token_both_kept_two_streams_and_an_alert(
    api_url: str,
    org,
    db,
    tmp_path: Path,  # noqa: ANN001
) -> None:
    fx = make_job(org.id, state="running")
    t0 = time.time() - 600
    qs = [TelemetryQueue(tmp_path / f"tablet{k}.sqlite", fx.machine_id) for k in (0, 1)]
    senders = [_sender(q, api_url, fx) for q in qs]
    try:
        for step in range(4):  # the two tablets take turns sending
            for k, (q, s) in enumerate(zip(qs, senders, strict=True)):
                base = t0 + step * 2.0 + k * 0.05
                q.put_many([record(fx, 0, t=base + 0.1 * i, cell=step) for i in range(20)])
                assert s.drain(10)
    finally:
        for s in senders:
            s.close()
    assert _count(db, fx.machine_id) == 160
    rows = _stored(db, fx.machine_id)
    by_stream = {q.stream[0]: [r[1] for r in rows if r[0] == q.stream[0]] for q in qs}
    assert all(sorted(v) == list(range(1, 81)) for v in by_stream.values())
    c = httpx.Client(base_url=api_url, headers=org.headers(), timeout=scaled(30))
    streams = c.get(f"/api/v1/machines/{fx.machine_id}/telemetry-streams").json()
    assert {s["stream"]: s["n_records"] for s in streams} == {q.stream[0]: 80 for q in qs}
    alerts = c.get(
        "/api/v1/alerts", params={"kind": "duplicate_stream", "machine_id": fx.machine_id}
    )
    assert alerts.status_code == 200, alerts.text
    mine = alerts.json()["items"]
    assert len(mine) == 1 and "both are stored" in mine[0]["message"]


def test_restored_queue_conflict_is_heard_and_nothing_is_dropped(
    api_url: str,
    org,
    db,
    tmp_path: Path,  # noqa: ANN001
) -> None:
    """A seq that goes backwards on a known stream (a queue restored from a copy, or cloned
    to a second tablet) is not a duplicate: the server stores none of it, acknowledges none
    of it, says so, and the agent goes on under a new stream."""
    fx = make_job(org.id, state="running")
    t0 = time.time() - 600
    qa = TelemetryQueue(tmp_path / "a.sqlite", fx.machine_id)
    qa.put_many([record(fx, 0, t=t0 + 0.1 * i, cell=0) for i in range(30)])
    sa = _sender(qa, api_url, fx)
    assert sa.drain(10)
    qa.close()
    shutil.copy(tmp_path / "a.sqlite", tmp_path / "b.sqlite")  # a backup of the state
    qa = TelemetryQueue(tmp_path / "a.sqlite", fx.machine_id)
    qa.put_many([record(fx, 0, t=t0 + 3.0 + 0.1 * i, cell=1) for i in range(30)])  # 31..60
    sa.queue = qa
    assert sa.drain(10)
    sa.close()
    qb = TelemetryQueue(tmp_path / "b.sqlite", fx.machine_id)  # restored: numbers 31.. again
    sid_a = qa.stats().get("stream")
    assert qb.stats().get("stream") == sid_a and qb.last_seq == 30
    qb.put_many([record(fx, 0, t=t0 + 10.0 + 0.1 * i, cell=2) for i in range(30)])
    sb = _sender(qb, api_url, fx)
    assert sb.drain(10)
    sb.close()
    assert _count(db, fx.machine_id) == 90  # the old code acknowledged qb's 30 unstored
    assert qb.stream[0] != sid_a  # moved to a new stream
    assert qb.reasons()["stream"] == {"stream conflict: switched to a new stream": 1}
    rows = _stored(db, fx.machine_id)
    assert [r for r in rows if r[0] == qb.stream[0]] == [
        (qb.stream[0], 31 + i, pytest.approx(t0 + 10.0 + 0.1 * i, abs=1e-5)) for i in range(30)
    ]


def test_wiped_queue_and_second_agent_over_mqtt(database_url: str, org, db, tmp_path: Path) -> None:  # noqa: ANN001
    """The same through the real Mosquitto and `fieldrx worker`: every agent of a machine
    hears every ack on the machine's ack topic and must trim only on its own stream's."""
    fx = make_job(org.id, state="running")
    t0 = time.time() - 600
    worker = start_worker(database_url, f"t{uuid.uuid4().hex[:8]}")

    host, port = mqtt_port()

    def sender(q: TelemetryQueue) -> MqttSender:
        # the broker binds machine N's login to client id fieldrx-edge-N: two tablets of one
        # machine take turns on the connection (each drains, then hands over)
        return MqttSender(
            q,
            MqttBroker(host, port, username=mqtt_username(fx.machine_id), password=fx.device_token),
            batch_size=25,
            ack_timeout_s=3.0,
        )

    try:
        q1 = TelemetryQueue(tmp_path / "a" / "queue.sqlite", fx.machine_id)
        q1.put_many([record(fx, 0, t=t0 + 0.1 * i) for i in range(100)])
        s1 = sender(q1)
        assert s1.drain(20)
        s1.close()
        sid1 = q1.stats().get("stream")
        q1.close()
        shutil.rmtree(tmp_path / "a")  # wiped: the next queue numbers from 1 again
        qs = [TelemetryQueue(tmp_path / f"t{k}.sqlite", fx.machine_id) for k in (0, 1)]
        for step in range(3):  # two tablets recording at once, sending in turns
            for k, q in enumerate(qs):
                base = t0 + 20.0 + step * 3.0 + k * 0.05
                q.put_many([record(fx, 0, t=base + 0.1 * i) for i in range(25)])
            for q in qs:
                s = sender(q)
                try:
                    assert s.drain(20)
                finally:
                    s.close()
    finally:
        worker.stop()
    assert _count(db, fx.machine_id) == 100 + 2 * 75
    rows = _stored(db, fx.machine_id)
    counts = {sid: sum(1 for r in rows if r[0] == sid) for sid in {r[0] for r in rows}}
    assert counts == {sid1: 100, qs[0].stream[0]: 75, qs[1].stream[0]: 75}
    assert all(q.stats()["rejected"] == 0 for q in qs)
    n_alerts = db.execute(
        text("SELECT count(*) FROM alerts WHERE machine_id = :m AND kind = 'duplicate_stream'"),
        {"m": fx.machine_id},
    ).scalar()
    assert n_alerts == 1
