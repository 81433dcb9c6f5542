"""End to end: a 12 m spreader on a server-planned 12 m plan with one
headland pass, driven by ``fieldrx-edge simulate --server`` against a real API process.

On a ~97.5 m x 192 m field the first inner swath overlaps the headland ring by more than
half the implement width, so its cells' polygons lie beside the driving line: the agent
located the landing point (on the line) in the finished ring cells and skipped the whole
swath (33 of 344 cells), and the job still ended "completed" without an alert. Now such
cells are located by their footprint rectangle and every prescribed cell is applied.

On the 96 m field a 0.17 m wide sliver between the ring and the first swath remains that
no pass can reach without double-applying a whole 12 m x 168 m footprint: the job-end
alert lists it and the report shows it.
"""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import httpx
import pytest

from tests.fleet.procs import BIN, ROOT, start_api
from tests.support import feature, machine_body, scaled

LON0, LAT0 = 7.90, 51.75


def lonlat_rect(width_m: float, height_m: float) -> dict:
    dl = 1.0 / (111_320.0 * math.cos(math.radians(LAT0)))
    dt = 1.0 / 111_200.0
    x1, y1 = LON0 + width_m * dl, LAT0 + height_m * dt
    ring = [[LON0, LAT0], [x1, LAT0], [x1, y1], [LON0, y1], [LON0, LAT0]]
    return {"type": "Polygon", "coordinates": [ring]}


@pytest.mark.parametrize(("width_m", "unreachable"), [(97.5, 0), (96.0, 1)])
def test_12m_one_headland_pass_every_cell_applied_or_alerted(
    database_url,
    org,
    tmp_path: Path,
    width_m: float,
    unreachable: int,  # noqa: ANN001
) -> None:
    api, url = start_api(database_url)
    try:
        c = httpx.Client(base_url=url, headers=org.headers(), timeout=scaled(120))
        geom = lonlat_rect(width_m, 192.0)
        field = c.post("/api/v1/fields", json=feature(geom, name="wide")).json()
        m = c.post("/api/v1/machines", json=machine_body("spreader", width_m=12.0)).json()
        token = c.post(f"/api/v1/machines/{m['id']}/device-token").json()["token"]
        plan = c.post(
            f"/api/v1/fields/{field['id']}/plans",
            json={"swath_width_m": 12.0, "cell_length_m": 5.0, "headland_passes": 1},
        )
        assert plan.status_code == 201, plan.text
        plan = plan.json()
        rx = c.post(
            f"/api/v1/plans/{plan['id']}/prescriptions",
            json={"model": "uniform", "params": {"rate_kg_ha": 150.0}, "machine_id": m["id"]},
        )
        assert rx.status_code == 201, rx.text
        job = c.post(
            "/api/v1/jobs", json={"prescription_id": rx.json()["id"], "machine_id": m["id"]}
        )
        assert job.status_code == 201, job.text
        job = job.json()
        assert c.post(f"/api/v1/jobs/{job['id']}/state", json={"state": "sent"}).status_code == 200
        dev = {"Authorization": f"Bearer {token}"}
        pkg = httpx.get(f"{url}/api/v1/device/jobs/{job['id']}/package", headers=dev)
        assert pkg.status_code == 200
        (tmp_path / "job.json").write_bytes(pkg.content)
        swaths = set(pkg.json()["swath"])
        assert len(swaths) == 8  # the ring and 7 inner swaths
        out = subprocess.run(
            [str(BIN / "fieldrx-edge"), "simulate", str(tmp_path / "job.json"), "--server", url,
             "--token", token, "--json", "--seed", "3", "--state-dir", str(tmp_path / "state"),
             "--compare-runs", "1"],
            cwd=ROOT, capture_output=True, text=True, timeout=scaled(300),
        )  # fmt: skip
        assert out.returncode == 0, out.stderr[-2000:]
        sim = json.loads(out.stdout.strip().splitlines()[-1])
        assert sim["telemetry_drained"] is True and sim["job_state_reported"] is True
        assert c.get(f"/api/v1/jobs/{job['id']}").json()["state"] == "completed"
        rep = c.get(f"/api/v1/jobs/{job['id']}/report").json()
        alerts = c.get("/api/v1/alerts", params={"job_id": job["id"]}).json()["items"]
    finally:
        api.stop()
    cells = {cell["seq"]: cell for cell in rep["cells"]}
    missing = sorted(
        s for s, cell in cells.items() if cell["target_rate_kg_ha"] > 0 and cell["m2_g"] <= 0
    )
    assert rep["not_applied_seqs"] == missing
    assert len(missing) == unreachable, missing
    assert rep["cells_applied"] == rep["cells_planned"] - unreachable
    ends = [a for a in alerts if a["kind"] == "cells_not_applied"]
    if unreachable:
        assert len(ends) == 1
        assert ends[0]["value"] == unreachable
        assert all(f"{s}" in ends[0]["message"] for s in missing)
    else:
        assert rep["coverage_pct"] == 100.0
        assert ends == []
    if not unreachable:
        # the swath that was skipped is applied over its footprint (eq. 17-18 accuracy)
        first_inner = [cell for cell in rep["cells"] if cell["swath"] == 1]
        assert len(first_inner) >= 30 and all(cell["m1_g"] > 0 for cell in first_inner)
        assert min(cell["accuracy_pct"] for cell in first_inner) > 80.0
        assert rep["mean_accuracy_pct"] > 95.0
