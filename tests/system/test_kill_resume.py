"""Acceptance: SIGKILL mid-run with the server down, restart, server back: every record once."""

import json
import os
import signal
import socket
import sqlite3
import subprocess
import sys
import time

from fieldrx_edge.jobs import JobStore
from fieldrx_edge.sim.drive import write_nmea_log
from fieldrx_edge.sim.simulator import SimConfig

from tests.edge.jobfactory import trial_plot
from tests.edge.peer import Peer
from tests.support import scaled


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


def last_seq(db):
    if not db.exists():
        return 0
    con = sqlite3.connect(db, timeout=scaled(5))
    try:
        row = con.execute("SELECT value FROM meta WHERE key='last_seq'").fetchone()
        return row[0] if row else 0
    except sqlite3.OperationalError:
        return 0
    finally:
        con.close()


def test_sigkill_offline_restart_delivers_every_record_once(tmp_path):
    job = trial_plot()
    state = tmp_path / "state"
    JobStore(state).save_package(job.to_json())
    log = tmp_path / "drive.nmea"
    n_fix = write_nmea_log(job, log, SimConfig(seed=4), max_s=150.0)
    port = free_port()
    url = f"http://127.0.0.1:{port}"
    cmd = [
        sys.executable,
        "-m",
        "fieldrx_edge.cli",
        "run",
        str(job.job_id),
        "--state-dir",
        str(state),
        "--source",
        f"file:{log}",
        "--replay-speed",
        "30",
        "--server",
        url,
        "--token",
        "dev-token",
        "--drain-timeout",
        "60",
    ]
    db = state / "queue.sqlite"
    p1 = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + scaled(30)
    while last_seq(db) < 400 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert p1.poll() is None, p1.stderr.read()
    os.kill(p1.pid, signal.SIGKILL)
    p1.wait()
    before = last_seq(db)
    assert before >= 400
    progress = json.loads((state / "progress" / f"{job.job_id}.json").read_text())
    assert progress["source_lines"] > 0

    p2 = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(1.5)
    peer = Peer(port=port).start()  # the server comes back
    try:
        out, err = p2.communicate(timeout=scaled(90))
        assert p2.returncode == 0, err
        res = json.loads(out.strip().splitlines()[-1])
        assert res["drained"] is True
        total = res["queue"]["last_seq"]
        assert total > before
        # resumed from the saved position: at most 50 lines (~17 fixes) are processed twice
        assert n_fix <= total <= n_fix + 20
        got = sorted(s for (m, s) in peer.records if m == job.machine_id)
        assert got == list(range(1, total + 1))  # every record, no gap
        assert peer.conflicts == 0  # a seq was never reused for different content
        assert res["queue"]["backlog"] == 0
    finally:
        peer.stop()
