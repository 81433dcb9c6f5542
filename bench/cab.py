"""The cab display's cost: decision-to-screen latency and the agent's CPU with the cab open
vs closed, one JSON line.

The agent drives one swath run of the demo job in real time at 10 Hz GNSS (seed 001's
receiver rate) through a ``JobSession``, twice: without the cab, then with the cab and one
screen connected (an SSE client in its own process, so its CPU is not the agent's). Latency
is the time from the session observing a record (the runtime's decision) to the screen's
process receiving the state that carries it, on the same clock.

    .venv/bin/python bench/cab.py [--runs 1]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from fieldrx_edge.cab.server import attach_cab
from fieldrx_edge.session import JobSession, UplinkOptions, load_job
from fieldrx_edge.sim.simulator import SimConfig, simulate

CLIENT = r"""
import json, sys, time, httpx
lat, n_prev, events, t0 = [], -1, 0, time.time()
with httpx.stream("GET", sys.argv[1] + "events", timeout=60) as r:
    for line in r.iter_lines():
        if not line.startswith("data: "):
            continue
        now = time.time()
        s = json.loads(line[6:])
        events += 1
        if s["n"] != n_prev and s["rec_wall"]:
            lat.append(now - s["rec_wall"])
            n_prev = s["n"]
        if s["state"] == "finished":
            break
print(json.dumps({"latency": lat, "events": events, "wall": time.time() - t0}))
"""


def drive(runs: int, cab: bool) -> dict[str, Any]:
    job = load_job("demo:35x23")
    tmp = Path(tempfile.mkdtemp(prefix="fieldrx-bench-cab-"))
    session = JobSession(job, UplinkOptions(offline=True), tmp / "queue.sqlite")
    client = None
    if cab:
        a = argparse.Namespace(cab="127.0.0.1:0", cab_token=None, cab_backlog_alarm=10**9,
                               cab_linger=0.0, cab_wait_start=False, sections=1)  # fmt: skip
        server = attach_cab(a, session, None)
        assert server is not None
        client = subprocess.Popen(
            [sys.executable, "-c", CLIENT, f"http://127.0.0.1:{server.port}/"],
            stdout=subprocess.PIPE,
            text=True,
        )
        time.sleep(1.0)  # the screen connects before the drive starts
    cpu0, wall0 = time.process_time(), time.perf_counter()
    simulate(job, SimConfig(seed=0, realtime=1.0, gnss_hz=10.0), sink=session.put_many,
             max_runs=runs)  # fmt: skip
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    out: dict[str, Any] = {"cpu_s": cpu, "wall_s": wall, "records": session.records}
    session.close()
    if client is not None:
        session.cab.finish()
        got = json.loads(client.communicate(timeout=60)[0])
        lat = np.asarray(got["latency"]) * 1000.0
        out.update(
            latency_p50_ms=float(np.percentile(lat, 50)),
            latency_p95_ms=float(np.percentile(lat, 95)),
            screen_updates_hz=got["events"] / max(got["wall"], 1e-9),
        )
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--runs", type=int, default=1, help="swath runs driven (each ~25 s)")
    a = p.parse_args()
    closed = drive(a.runs, cab=False)
    opened = drive(a.runs, cab=True)

    def share(d: dict[str, Any]) -> float:
        return float(d["cpu_s"] / d["wall_s"])  # cores busy over the drive

    print(
        json.dumps(
            {
                "gnss_hz": 10.0,
                "records": opened["records"],
                "latency_p50_ms": round(opened["latency_p50_ms"], 1),
                "latency_p95_ms": round(opened["latency_p95_ms"], 1),
                "screen_updates_hz": round(opened["screen_updates_hz"], 1),
                "cpu_closed_pct_of_core": round(100 * share(closed), 2),
                "cpu_open_pct_of_core": round(100 * share(opened), 2),
                "cab_cost_pct_of_core": round(100 * (share(opened) - share(closed)), 2),
            }
        )
    )


if __name__ == "__main__":
    main()
