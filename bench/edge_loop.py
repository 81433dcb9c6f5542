"""Edge agent hot loop: fixes/s through the whole GNSS pipeline, locator vs naive scan.

Job: ~100,000 cells (500 swaths x 200 cells of 5 m x 2.3 m). Input: an NMEA
log (RMC + GGA + VTG per epoch, 10 Hz) of a tractor driving that job's path.
Pipeline per fix: NMEA parse -> UTM -> Kalman -> look-ahead -> boundary ->
path-ordered cell lookup -> rate -> shaft rpm -> telemetry record dict.
The locator is timed against a naive (numpy-vectorised) scan of every cell on
the same points, in the same run. Ends with one JSON line.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fieldrx_edge.gnss import NmeaParser  # noqa: E402
from fieldrx_edge.locate import CellLocator  # noqa: E402
from fieldrx_edge.runtime import Measured, Pipeline, RuntimeConfig, make_record  # noqa: E402
from fieldrx_edge.sim.drive import drive_fixes, write_nmea_log  # noqa: E402
from fieldrx_edge.sim.simulator import SimConfig  # noqa: E402
from fieldrx_edge.uplink import TelemetryQueue  # noqa: E402

from tests.edge.jobfactory import big_grid  # noqa: E402


def main() -> None:
    t = time.perf_counter()
    job = big_grid(100_000)
    print(f"job: {job.n_cells} cells, built in {time.perf_counter() - t:.1f} s")
    tmp = Path(tempfile.mkdtemp(prefix="edge-bench-"))
    log = tmp / "drive.nmea"
    n_epochs = write_nmea_log(job, log, SimConfig(seed=1), max_s=3000.0)
    lines = log.read_text().splitlines()
    print(f"log: {n_epochs} epochs, {len(lines)} lines")

    # 1. whole pipeline, in memory
    best = 0.0
    for _ in range(3):
        parser = NmeaParser()
        pipe = Pipeline(job, RuntimeConfig())
        n = 0
        t = time.perf_counter()
        for ln in lines:
            for fx in parser.feed(ln):
                d = pipe.on_fix(fx, fx.t or 0.0)
                make_record(pipe, d, fx, Measured(100.0, 80.0, True, fx.t or 1.0))
                n += 1
        best = max(best, n / (time.perf_counter() - t))
    print(f"pipeline (parse..record): {best:,.0f} fixes/s ({n} fixes)")
    assert n == n_epochs

    # 2. the same plus the durable queue (records committed 100 per transaction)
    q = TelemetryQueue(tmp / "q.sqlite", job.machine_id)
    parser = NmeaParser()
    pipe = Pipeline(job, RuntimeConfig())
    buf = []
    t = time.perf_counter()
    for ln in lines:
        for fx in parser.feed(ln):
            d = pipe.on_fix(fx, fx.t or 0.0)
            buf.append(make_record(pipe, d, fx, Measured(100.0, 80.0, True, fx.t or 1.0)))
            if len(buf) == 100:
                q.put_many(buf)
                buf = []
    if buf:
        q.put_many(buf)
    queued_fps = n_epochs / (time.perf_counter() - t)
    print(f"pipeline + SQLite queue: {queued_fps:,.0f} fixes/s (last seq {q.last_seq})")

    # 3. locator vs naive scan on the landing points of the drive
    f = drive_fixes(job, SimConfig(seed=2), max_s=3000.0)
    pts = list(zip(f["x"].tolist(), f["y"].tolist(), strict=True))
    loc = CellLocator(job.corners_utm)
    t = time.perf_counter()
    found = [loc.locate(x, y) for x, y in pts]
    per_fast = (time.perf_counter() - t) / len(pts)
    sub = pts[:: max(1, len(pts) // 300)]
    t = time.perf_counter()
    naive = [loc.locate_naive(x, y) for x, y in sub]
    per_naive = (time.perf_counter() - t) / len(sub)
    idx = list(range(0, len(pts), max(1, len(pts) // 300)))
    agree = sum(1 for i, k in zip(idx, naive, strict=True) if found[i] == k) / len(naive)
    # off-path queries (grid-hash fallback every time)
    rng = np.random.default_rng(0)
    cx = np.asarray(job.corners_utm).reshape(-1, 8)[:, 0::2]
    cy = np.asarray(job.corners_utm).reshape(-1, 8)[:, 1::2]
    rx = rng.uniform(cx.min(), cx.max(), 20000)
    ry = rng.uniform(cy.min(), cy.max(), 20000)
    loc2 = CellLocator(job.corners_utm)
    t = time.perf_counter()
    for x, y in zip(rx.tolist(), ry.tolist(), strict=True):
        loc2.locate(x, y)
    per_random = (time.perf_counter() - t) / len(rx)
    ratio = per_naive / per_fast
    print(
        f"locator on path: {per_fast * 1e6:.2f} us/fix, random points (fallback):"
        f" {per_random * 1e6:.2f} us, naive scan: {per_naive * 1e6:.0f} us"
        f" -> {ratio:,.0f}x faster (agreement {agree:.3f}, fallbacks {loc.fallbacks})"
    )
    print(
        json.dumps(
            {
                "bench": "edge_loop",
                "cells": job.n_cells,
                "fixes": n_epochs,
                "pipeline_fixes_per_s": round(best),
                "pipeline_with_queue_fixes_per_s": round(queued_fps),
                "locator_us": round(per_fast * 1e6, 3),
                "locator_random_us": round(per_random * 1e6, 3),
                "naive_us": round(per_naive * 1e6, 1),
                "locator_speedup": round(ratio, 1),
                "agreement": agree,
            }
        )
    )


if __name__ == "__main__":
    main()
