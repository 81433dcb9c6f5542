"""Variable-rate seeding end to end: a prescription in seeds/ha from the samples' NDVI and a
maize seed lot, its ISOXML read back by an independent reader (the ``isoxml`` package), a
``seeding_rate`` job driven by ``fieldrx-edge simulate --server`` on a drill whose roller
is calibrated in g per revolution, and the report's totals in seeds.

The lot: thousand-kernel weight 320 g, germination 95 %: one seed/ha is
320 / 1e6 / 0.95 kg/ha (``fieldrx_edge.rateunits``' seeds/ha), so 60 000 seeds/ha is
20.2 kg/ha, which the drill meters by mass, and DDI 11 (count per area, 0.001 /m^2)
carries 6 000 for it."""

from __future__ import annotations

import io
import json
import subprocess
import zipfile
from pathlib import Path

import httpx
import numpy as np
import pytest
from isoxml.converter.np_grid import to_numpy_array
from isoxml.util.isoxml_io import isoxml_from_path

from tests.fleet.procs import BIN, ROOT, start_api
from tests.support import feature, machine_body, scaled
from tests.support.prescriptions import FIELD, samples_csv

LOT = {"tkw_g": 320.0, "germination_pct": 95.0}
KG_PER_SEED_HA = 320.0 / 1e6 / 0.95
# a drill's fluted roller: 30 g per revolution, 6-40 r/min (a calibration test's result)
DRILL = {"kind": "table", "rpm": [5.0, 40.0], "g_per_rev": [30.0, 30.0], "min_rpm": 6.0,
         "max_rpm": 40.0}  # fmt: skip


def read_taskdata(data: bytes, tmp: Path) -> tuple[object, dict]:
    zipfile.ZipFile(io.BytesIO(data)).extractall(tmp)
    return isoxml_from_path(tmp / "TASKDATA")


@pytest.mark.slow
def test_variable_rate_seeding_end_to_end(database_url, org, tmp_path: Path) -> None:  # noqa: ANN001
    api, url = start_api(database_url)
    try:
        c = httpx.Client(base_url=url, headers=org.headers(), timeout=scaled(60))
        field = c.post("/api/v1/fields", json=feature(FIELD, name="maize")).json()
        r = c.post(
            f"/api/v1/fields/{field['id']}/soil-samples",
            files={"file": ("s.csv", samples_csv(), "text/csv")},
        )
        assert r.status_code == 201, r.text
        drill = c.post(
            "/api/v1/machines",
            json=machine_body("Drill", 2.3, calibration=DRILL, implement_type="seeder"),
        )
        assert drill.status_code == 201, drill.text
        drill = drill.json()
        token = c.post(f"/api/v1/machines/{drill['id']}/device-token").json()["token"]
        plan = c.post(
            f"/api/v1/fields/{field['id']}/plans",
            json={"swath_width_m": 2.3, "cell_length_m": 5.0},
        ).json()
        body = {"model": "seeding_ndvi", "rate_unit": "seeds/ha", "product": "Maize hybrid",
                "lot": LOT, "machine_id": drill["id"]}  # fmt: skip
        rx = c.post(f"/api/v1/plans/{plan['id']}/prescriptions", json=body)
        assert rx.status_code == 201, rx.text
        rx = rx.json()
        assert rx["rate_unit"] == "seeds/ha" and rx["lot"] == LOT
        assert rx["kg_per_unit"] == pytest.approx(KG_PER_SEED_HA)
        cells = c.get(f"/api/v1/prescriptions/{rx['id']}/cells?limit=5000").json()["features"]
        seeds = np.array([f["properties"]["rate_kg_ha"] for f in cells]) / KG_PER_SEED_HA
        # the samples' NDVI runs 0.2-0.5: 60 000 (clamped at NDVI <= 0.3) to 72 000 seeds/ha
        assert seeds.min() == pytest.approx(60_000, rel=1e-6) and 66_000 < seeds.max() <= 72_001
        # a seed lot without its germination is refused, naming it and its range
        r = c.post(
            f"/api/v1/plans/{plan['id']}/prescriptions",
            json={**body, "lot": {"tkw_g": 320.0}},
        )
        assert r.status_code == 422 and "germination" in r.text and "50-100 %" in r.text, r.text
        # a fertiliser is not a seed lot: refused, not sown with nutrient figures beside it
        r = c.post(
            f"/api/v1/plans/{plan['id']}/prescriptions",
            json={**body, "product_key": "default:urea"},
        )
        assert r.status_code == 422 and "is a fertiliser (46 n_pct)" in r.text, r.text
        summary = rx["summary"]
        assert summary["product"]["name"] == "Maize hybrid" and summary.get("nutrients_kg") is None

        # ISOXML: count-per-area setpoints (DDI 11, 0.001 /m^2 = 10 seeds/ha), read back
        g = c.get(f"/api/v1/prescriptions/{rx['id']}/export?format=isoxml")
        assert g.status_code == 200, g.text
        task_data, refs = read_taskdata(g.content, tmp_path / "grid")
        task = task_data.tasks[0]
        tzn = {t.code: t for t in task.treatment_zones}
        assert tzn[1].process_data_variables[0].process_data_ddi == bytes.fromhex("000B")
        arr = to_numpy_array(refs["GRD00001"], task.grids[0])
        values = set(np.unique(arr).tolist()) - {0}
        assert min(values) == 6_000 and max(values) <= 7_200
        z = c.get(f"/api/v1/prescriptions/{rx['id']}/export?format=isoxml-zones")
        assert z.status_code == 200, z.text
        zones, _ = read_taskdata(z.content, tmp_path / "zones")
        pdvs = [p for t in zones.tasks[0].treatment_zones for p in t.process_data_variables]
        assert {p.process_data_ddi for p in pdvs} == {bytes.fromhex("000B")}
        assert any("seeds/ha" in (t.designator or "") for t in zones.tasks[0].treatment_zones)

        # a fertiliser kind is not sent a seeding prescription
        r = c.post("/api/v1/jobs", json={"prescription_id": rx["id"], "machine_id": drill["id"]})
        assert r.status_code == 422 and "is in seeds/ha" in r.text, r.text
        job = c.post(
            "/api/v1/jobs",
            json={"kind": "seeding_rate", "prescription_id": rx["id"], "machine_id": drill["id"]},
        )
        assert job.status_code == 201, job.text
        job = job.json()
        sent = c.post(f"/api/v1/jobs/{job['id']}/state", json={"state": "sent"})
        assert sent.status_code == 200, sent.text
        dev = {"Authorization": f"Bearer {token}"}
        pkg = httpx.get(f"{url}/api/v1/device/jobs/{job['id']}/package", headers=dev)
        assert pkg.status_code == 200
        p = pkg.json()
        assert p["kind"] == "seeding_rate" and p["rate_unit"] == "seeds/ha"
        assert p["unit_lot"] == LOT and min(p["rate_kg_ha"]) == pytest.approx(60_000, rel=1e-6)
        (tmp_path / "job.json").write_bytes(pkg.content)
        out = subprocess.run(
            [str(BIN / "fieldrx-edge"), "simulate", str(tmp_path / "job.json"), "--server", url,
             "--token", token, "--json", "--seed", "3", "--state-dir", str(tmp_path / "state")],
            cwd=ROOT, capture_output=True, text=True, timeout=scaled(120),
        )  # fmt: skip
        assert out.returncode == 0, out.stderr[-2000:]
        sim = json.loads(out.stdout.strip().splitlines()[-1])
        assert sim["telemetry_drained"] is True and sim["job_state_reported"] is True
        rep = c.get(f"/api/v1/jobs/{job['id']}/report").json()
        assert c.get(f"/api/v1/jobs/{job['id']}").json()["state"] == "completed"
    finally:
        api.stop()
    unit = rep["unit"]
    assert unit["rate_unit"] == "seeds/ha" and unit["total_unit"] == "seeds"
    assert unit["kg_per_unit"] == pytest.approx(KG_PER_SEED_HA)
    assert unit["planned_total"] == pytest.approx(rep["planned_total_kg"] / KG_PER_SEED_HA)
    # about 0.24 ha at 60 000-72 000 seeds/ha
    assert 12_000 < unit["planned_total"] < 18_000
    # the drill sowed what was prescribed, within the controller's and the log's accuracy
    assert unit["applied_total"] == pytest.approx(unit["planned_total"], rel=0.08)
    assert rep["mean_accuracy_pct"] > 90
