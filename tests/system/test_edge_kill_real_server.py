"""The acceptance test against the REAL server: SIGKILL the agent mid-run while the FieldRx API
is unreachable, restart it, bring the API back, and find every record stored exactly once."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import httpx
from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.jobs import JobStore
from fieldrx_edge.sim.drive import write_nmea_log
from fieldrx_edge.sim.simulator import SimConfig
from sqlalchemy import text

from tests.fleet.helpers import make_job
from tests.fleet.procs import free_port, start_api
from tests.support import scaled


def _last_seq(db: Path) -> int:
    if not db.exists():
        return 0
    con = sqlite3.connect(db, timeout=scaled(5))
    try:
        row = con.execute("SELECT value FROM meta WHERE key='last_seq'").fetchone()
        return int(row[0]) if row else 0
    except sqlite3.OperationalError:
        return 0
    finally:
        con.close()


def test_sigkill_with_server_down_then_every_record_once(database_url, org, db, tmp_path) -> None:  # noqa: ANN001
    fx = make_job(org.id, state="sent")
    port = free_port()
    url = f"http://127.0.0.1:{port}"
    api, _ = start_api(database_url, port)
    try:  # download the package as the tractor does, then the server goes away
        r = httpx.get(f"{url}/api/v1/device/jobs/{fx.job_id}/package", headers=fx.device_headers)
        assert r.status_code == 200, r.text
        job = JobPackage.from_json(r.content)
    finally:
        api.stop()
    state = tmp_path / "state"
    JobStore(state).save_package(job.to_json())
    log = tmp_path / "drive.nmea"
    n_fix = write_nmea_log(job, log, SimConfig(seed=7), max_s=120.0)
    cmd = [
        sys.executable, "-m", "fieldrx_edge.cli", "run", str(job.job_id),
        "--state-dir", str(state), "--source", f"file:{log}", "--replay-speed", "30",
        "--server", url, "--token", fx.device_token, "--drain-timeout", "60",
    ]  # fmt: skip
    queue_db = state / "queue.sqlite"
    p1 = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + scaled(30)
    while _last_seq(queue_db) < 300 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert p1.poll() is None, p1.stderr.read() if p1.stderr else ""
    os.kill(p1.pid, signal.SIGKILL)
    p1.wait()
    assert _last_seq(queue_db) >= 300

    p2 = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(1.5)
    api, _ = start_api(database_url, port)  # the server comes back
    try:
        out, err = p2.communicate(timeout=scaled(120))
        assert p2.returncode == 0, err
        res = json.loads(out.strip().splitlines()[-1])
        assert res["drained"] is True and res["queue"]["backlog"] == 0
        total = res["queue"]["last_seq"]
        assert n_fix <= total <= n_fix + 20  # resumed where the killed run stopped
        rows = db.execute(
            text("SELECT seq FROM telemetry WHERE machine_id = :m ORDER BY seq"),
            {"m": fx.machine_id},
        ).all()
        seqs = [r[0] for r in rows]
        assert seqs == list(range(1, total + 1))  # every record, once, no gap
        status = httpx.get(f"{url}/api/v1/machines/status", headers=org.headers()).json()
        mine = [m for m in status["items"] if m["machine_id"] == fx.machine_id]
        assert mine and mine[0]["acked_seq"] == total
    finally:
        api.stop()
