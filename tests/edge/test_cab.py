"""The cab display served by the agent: pairing token beyond localhost, the operator's
buttons acting on the one session's records, alarms latched until acknowledged, coverage
painted from the records the session queued (real HTTP server, real queue, real simulator)."""

from __future__ import annotations

import argparse
import json
import threading
from pathlib import Path
from typing import Any

import httpx
import pytest
from fieldrx_edge.cab.server import attach_cab
from fieldrx_edge.session import JobSession, UplinkOptions, load_job
from fieldrx_edge.sim.simulator import SimConfig, simulate


def _args(**kw: Any) -> argparse.Namespace:
    base = {"cab": "127.0.0.1:0", "cab_token": None, "cab_backlog_alarm": 3000,
            "cab_linger": 0.0, "cab_wait_start": False, "sections": 2}  # fmt: skip
    base.update(kw)
    return argparse.Namespace(**base)


def _session(tmp_path: Path, **kw: Any) -> tuple[JobSession, Any]:
    job = load_job("demo:35x23")
    s = JobSession(job, UplinkOptions(offline=True), tmp_path / "queue.sqlite")
    cab = attach_cab(_args(**kw), s, None)
    assert cab is not None
    return s, cab


def test_beyond_localhost_needs_the_pairing_token(tmp_path: Path) -> None:
    s, cab = _session(tmp_path, cab="0.0.0.0:0", cab_token="tractor-7-pin")
    try:
        base = f"http://127.0.0.1:{cab.port}"
        for path in ("/", "/api/job", "/api/state", "/static/cab.js"):
            r = httpx.get(base + path, timeout=10)
            assert r.status_code == 401, path
            assert "pairing token" in r.text
        assert httpx.get(base + "/api/job?token=wrong", timeout=10).status_code == 401
        r = httpx.post(base + "/api/control", json={"action": "pause"}, timeout=10)
        assert r.status_code == 401 and s.operator.paused is False  # refused, nothing done
        r = httpx.get(base + "/?token=tractor-7-pin", timeout=10)
        assert r.status_code == 200 and "cab.js" in r.text
        cookie = r.headers["set-cookie"].split(";")[0]
        r = httpx.get(base + "/api/job", headers={"Cookie": cookie}, timeout=10)
        assert r.status_code == 200 and r.json()["job_id"] == s.job.job_id
        r = httpx.get(base + "/api/state", headers={"X-Cab-Token": "tractor-7-pin"}, timeout=10)
        assert r.status_code == 200
    finally:
        cab.close()


def test_no_token_given_beyond_localhost_makes_one(tmp_path: Path) -> None:
    s, cab = _session(tmp_path, cab="0.0.0.0:0")
    try:
        assert cab.token and len(cab.token) >= 12
        base = f"http://127.0.0.1:{cab.port}"
        assert httpx.get(base + "/api/job", timeout=10).status_code == 401
        assert httpx.get(base + f"/api/job?token={cab.token}", timeout=10).status_code == 200
    finally:
        cab.close()


def test_localhost_is_open_and_assets_are_the_agents_own(tmp_path: Path) -> None:
    s, cab = _session(tmp_path)
    try:
        base = f"http://127.0.0.1:{cab.port}"
        page = httpx.get(base + "/", timeout=10).text
        assert "http" not in page.replace(base, "")  # no CDN: every asset from the agent
        assert httpx.get(base + "/static/cab.css", timeout=10).status_code == 200
        assert httpx.get(base + "/static/../server.py", timeout=10).status_code == 404
    finally:
        cab.close()


def _control(cab: Any, body: dict[str, Any]) -> httpx.Response:
    return httpx.post(f"http://127.0.0.1:{cab.port}/api/control", json=body, timeout=10)


def test_operator_actions_reach_the_meter_and_every_record(tmp_path: Path) -> None:
    """Buttons act through the session: a +10 % override raises the shaft target, pause
    stops it, and each record written meanwhile carries the operator's tag."""
    s, cab = _session(tmp_path)
    try:
        bad = _control(cab, {"action": "override", "steps": 11})
        assert bad.status_code == 400 and "steps must be an integer" in bad.json()["error"]
        assert _control(cab, {"action": "override", "steps": 10}).status_code == 200
        bad = _control(cab, {"action": "override", "steps": 1})
        assert bad.status_code == 400 and "beyond +-50 %" in bad.json()["error"]
        assert s.operator.override_pct == 50.0  # the refused step changed nothing
        assert _control(cab, {"action": "override", "steps": -8}).status_code == 200
        assert s.operator.override_pct == 10.0
        assert _control(cab, {"action": "nonsense"}).status_code == 400
        bad = _control(cab, {"action": "pull"})  # an offline tractor has no server to ask
        assert bad.status_code == 400 and "no server configured" in bad.json()["error"]
        recs: list[dict[str, Any]] = []
        s.observers.append(recs.append)
        job = s.job
        cfg = SimConfig(seed=1, implement=s.operator)
        res = simulate(job, cfg, sink=s.put_many)
        assert res.n_fixes > 0
        metering = [r for r in recs if (r["target_shaft_rpm"] or 0) > 0]
        assert metering and all("operator_rate_override" in r["alarms"] for r in recs)
        _control(cab, {"action": "pause"})
        recs.clear()
        simulate(job, cfg, sink=s.put_many, max_runs=1)
        assert recs and all("operator_pause" in r["alarms"] for r in recs)
        assert all((r["actual_shaft_rpm"] or 0) < 1.0 for r in recs[len(recs) // 2 :])
        pending = s.queue.pending(limit=100_000)
        assert any("operator_pause" in r["alarms"] for r in pending)  # queued for the server
    finally:
        cab.close()


def test_alarm_latched_until_acknowledged_and_the_ack_is_sent(tmp_path: Path) -> None:
    s, cab = _session(tmp_path, cab_backlog_alarm=5)
    try:
        job = s.job
        simulate(job, SimConfig(seed=2), sink=s.put_many, max_runs=1)
        state = httpx.get(f"http://127.0.0.1:{cab.port}/api/state", timeout=10).json()
        names = {a["name"]: a for a in state["alarms"]}
        assert "uplink_backlog_high" in names and not names["uplink_backlog_high"]["acked"]
        r = _control(cab, {"action": "ack"})
        assert "uplink_backlog_high" in r.json()["acknowledged"]
        recs: list[dict[str, Any]] = []
        s.observers.append(recs.append)
        s.put_many([dict(job_rec) for job_rec in s.queue.pending(limit=1)])
        assert "alarm_ack" in recs[0]["alarms"] and "uplink_backlog_high" in recs[0]["alarms"]
        state = httpx.get(f"http://127.0.0.1:{cab.port}/api/state", timeout=10).json()
        assert {a["name"]: a["acked"] for a in state["alarms"]}["uplink_backlog_high"] is True
    finally:
        cab.close()


def test_painted_coverage_is_the_records_applied_cells(tmp_path: Path) -> None:
    s, cab = _session(tmp_path)
    try:
        got: list[int] = []
        done = threading.Event()

        def listen() -> None:
            with httpx.stream("GET", f"http://127.0.0.1:{cab.port}/events", timeout=30) as r:
                for line in r.iter_lines():
                    if line.startswith("data: "):
                        snap = json.loads(line[6:])
                        got.extend(snap["new_cells"])
                        if snap["state"] == "finished":
                            done.set()
                            return

        th = threading.Thread(target=listen, daemon=True)
        th.start()
        simulate(s.job, SimConfig(seed=3), sink=s.put_many)
        s.close()
        recs = s.queue.pending(limit=100_000)
        applied = {
            r["cell_seq"] for r in recs
            if r["implement_down"] and r["cell_seq"] is not None and r["applied_rate_kg_ha"] > 0
        }  # fmt: skip
        s.cab.finish()
        assert done.wait(30)
        assert applied and set(got) == applied and len(got) == len(applied)
    finally:
        cab.close()


@pytest.mark.parametrize("spec", ["x", "host:99999"])
def test_bad_bind_is_refused_clearly(tmp_path: Path, spec: str) -> None:
    job = load_job("demo:35x23")
    s = JobSession(job, UplinkOptions(offline=True), tmp_path / "queue.sqlite")
    with pytest.raises(SystemExit, match="--cab"):
        attach_cab(_args(cab=spec), s, None)


def test_run_with_the_cab_override_reaches_the_motor_and_finish_stops_the_loop(
    tmp_path: Path,
) -> None:
    """``run --cab``: the same loop as without it; the operator stands between the runtime
    and the motor (a +20 % override raises the shaft target it gets) and Finish ends it."""
    import subprocess
    import sys
    import time

    from fieldrx_edge.sim.drive import write_nmea_log

    job = load_job("demo:35x23")
    pkg = tmp_path / "job.json"
    pkg.write_bytes(job.to_json())
    log = tmp_path / "drive.nmea"
    n_fix = write_nmea_log(job, log, SimConfig(seed=5), max_s=300.0)
    p = subprocess.Popen(
        [sys.executable, "-m", "fieldrx_edge.cli", "run", str(pkg), "--state-dir",
         str(tmp_path / "state"), "--source", f"file:{log}", "--replay-speed", "2",
         "--offline", "--cab", "0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert p.stderr is not None
        port = json.loads(p.stderr.readline())["port"]
        base = f"http://127.0.0.1:{port}"
        deadline = time.monotonic() + 120
        snap: dict[str, Any] = {}
        while time.monotonic() < deadline:  # the loop meters before the operator acts
            snap = httpx.get(base + "/api/state", timeout=10).json()
            if (snap["rec"].get("target_shaft_rpm") or 0) > 0:
                break
            time.sleep(0.2)
        assert (snap["rec"].get("target_shaft_rpm") or 0) > 0, "never metered"
        httpx.post(base + "/api/control", json={"action": "override", "steps": 4}, timeout=10)
        raised = None  # the motor follows target x 1.2 (or the meter's limit, said so)
        while time.monotonic() < deadline and raised is None:
            st = httpx.get(base + "/api/state", timeout=10).json()
            rec = st["rec"]
            tr, ar = rec["target_shaft_rpm"] or 0.0, rec["actual_shaft_rpm"] or 0.0
            if "operator_rate_override" in rec["alarms"] and tr > 0:
                if ar > 1.12 * tr or st["operator"]["limited"]:
                    raised = rec
            time.sleep(0.1)
        assert raised is not None
        httpx.post(base + "/api/control", json={"action": "finish"}, timeout=10)
        out, _ = p.communicate(timeout=120)
    finally:
        p.kill()
    res = json.loads(out.strip().splitlines()[-1])
    assert p.returncode == 0
    # stopped by Finish, not at the log's end
    assert res["records"] < n_fix and res["finished_cells"] < job.n_cells


@pytest.mark.parametrize("spec", ["demo:35x23", "seeding"])
def test_finish_ends_a_simulated_drive_where_it_is(tmp_path: Path, spec: str) -> None:
    import subprocess
    import sys
    import time

    if spec == "seeding":
        from tests.edge.test_jobkinds import kind_job

        job_file = tmp_path / "job.json"
        job_file.write_bytes(kind_job("seeding_depth").to_json())
        spec = str(job_file)
    p = subprocess.Popen(
        [sys.executable, "-m", "fieldrx_edge.cli", "simulate", spec, "--realtime", "5",
         "--cab", "0", "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert p.stderr is not None
        base = f"http://127.0.0.1:{json.loads(p.stderr.readline())['port']}"
        deadline = time.monotonic() + 120
        while httpx.get(base + "/api/state", timeout=10).json()["n"] < 20:
            assert time.monotonic() < deadline, "no records"
            time.sleep(0.2)
        httpx.post(base + "/api/control", json={"action": "finish"}, timeout=10)
        out, _ = p.communicate(timeout=120)
    finally:
        p.kill()
    res = json.loads(out.strip().splitlines()[-1])
    assert p.returncode == 0 and res["finished_early"] is True and res["records"] >= 20


def test_a_sensor_job_refuses_the_hand_it_cannot_apply(tmp_path: Path) -> None:
    """The sensor kinds' loops have no operator hook: pause or an override is refused with
    the reason, never recorded as if the meter had followed it."""
    from tests.edge.test_jobkinds import kind_job

    job = kind_job("ndvi_topdress")
    s = JobSession(job, UplinkOptions(offline=True), tmp_path / "queue.sqlite")
    cab = attach_cab(_args(), s, None)
    assert cab is not None
    try:
        for body in ({"action": "pause"}, {"action": "override", "steps": 1}):
            r = _control(cab, body)
            assert r.status_code == 400 and "not available on a ndvi_topdress job" in r.text
        assert s.operator.to_dict()["paused"] is False and s.operator.override_pct == 0.0
        assert _control(cab, {"action": "ack"}).status_code == 200
    finally:
        cab.close()
