"""Issue 7 acceptance: a job driven by `fieldrx-edge simulate --server` is reported per cell
as the simulator itself reports it (seed 001 eq. 17-18).

With a headland pass both sides attribute landed mass to the real cell polygons (the job
package's shapes on the tractor, plan_cells.geom on the server), so the headland ring must
agree as closely as the plain grid."""

from __future__ import annotations

import csv
import json
import subprocess
from pathlib import Path

import httpx
import numpy as np
import pytest

from tests.fleet.procs import BIN, ROOT, start_api
from tests.support import SEED001_CAL, SMALL_PLOT, feature, machine_body


@pytest.mark.parametrize("headland_passes", [0, 1])
def test_simulated_job_report_matches_simulator(
    database_url,
    org,
    tmp_path: Path,
    headland_passes: int,  # noqa: ANN001
) -> None:
    api, url = start_api(database_url)
    try:
        c = httpx.Client(base_url=url, headers=org.headers(), timeout=60)
        field = c.post("/api/v1/fields", json=feature(SMALL_PLOT, name="trial plot")).json()
        # floor 10 r/min: the 220..340 kg/ha edits below are meterable at 0.8..2.5 m/s
        # (seed 001's 30 r/min floor is 608 kg/ha at 0.8 m/s, and edits it cannot meter are refused)
        cal = {**SEED001_CAL, "min_rpm": 10.0}
        m = c.post("/api/v1/machines", json=machine_body("sim", 2.3, calibration=cal)).json()
        token = c.post(f"/api/v1/machines/{m['id']}/device-token").json()["token"]
        plan = c.post(
            f"/api/v1/fields/{field['id']}/plans",
            json={"swath_width_m": 2.3, "cell_length_m": 5.0, "headland_passes": headland_passes},
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
        r = c.post(f"/api/v1/prescriptions/{rx['id']}/edits", json={"cells": edits})
        assert r.status_code == 201, r.text
        job = c.post("/api/v1/jobs", json={"prescription_id": rx["id"], "machine_id": m["id"]})
        assert job.status_code == 201, job.text
        job = job.json()
        assert c.post(f"/api/v1/jobs/{job['id']}/state", json={"state": "sent"}).status_code == 200
        dev = {"Authorization": f"Bearer {token}"}
        pkg = httpx.get(f"{url}/api/v1/device/jobs/{job['id']}/package", headers=dev)
        assert pkg.status_code == 200
        (tmp_path / "job.json").write_bytes(pkg.content)
        if headland_passes:  # the ring's corner and clipped cells carry their real shapes
            assert len(pkg.json()["shape_seq"]) >= 4
        cells_csv = tmp_path / "cells.csv"
        out = subprocess.run(
            [str(BIN / "fieldrx-edge"), "simulate", str(tmp_path / "job.json"), "--server", url,
             "--token", token, "--cells-out", str(cells_csv), "--json", "--seed", "3",
             "--state-dir", str(tmp_path / "state"), "--compare-runs", "1"],
            cwd=ROOT, capture_output=True, text=True, timeout=120,
        )  # fmt: skip
        assert out.returncode == 0, out.stderr[-2000:]
        sim = json.loads(out.stdout.strip().splitlines()[-1])
        assert sim["telemetry_drained"] is True
        assert sim["job_state_reported"] is True
        rep = c.get(f"/api/v1/jobs/{job['id']}/report").json()
        assert c.get(f"/api/v1/jobs/{job['id']}").json()["state"] == "completed"
    finally:
        api.stop()
    sim_cells = {int(r["seq"]): r for r in csv.DictReader(cells_csv.open())}
    ours = {cell["seq"]: cell for cell in rep["cells"]}
    seqs = sorted(sim_cells)
    assert len(seqs) > 20
    m1_sim = np.array([float(sim_cells[s]["m1_g"]) for s in seqs])
    m1_srv = np.array([ours[s]["m1_g"] for s in seqs])
    acc_sim = np.array([float(sim_cells[s]["accuracy_pct"]) for s in seqs])
    acc_srv = np.array([ours[s]["accuracy_pct"] for s in seqs])
    # the planned mass is the same definition (eq. 17, driven length x width)
    np.testing.assert_allclose(m1_srv, m1_sim, rtol=0.01, atol=0.5)
    # per-cell accuracy from telemetry vs the simulator's own landing model (measured, plain
    # grid: mean 98.67 vs 99.18 %, per-cell |diff| mean 0.67, max 2.9; headland: 0.79, max 4.24)
    assert abs(acc_srv.mean() - sim["mean_accuracy_pct"]) < 1.0
    assert np.mean(np.abs(acc_srv - acc_sim)) < 1.0
    assert np.max(np.abs(acc_srv - acc_sim)) < 5.0
    assert rep["n_records"] == sim["telemetry"]["last_seq"]
