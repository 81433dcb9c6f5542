"""One set of numbers: a prescription version's area and planned amount, a job's planned and
applied amounts and areas, and the field's area read from every screen, print view and file
that shows them are the same quantity (to 0.01 %), and no sum of cell areas exceeds the field.

The field is L-shaped with a slanted inner edge (clipped cells, a headland ring whose
corners overlap), the version has two edits, and the job is driven by
``fieldrx-edge simulate --server``: the real agent, API, ingest and exports."""

from __future__ import annotations

import csv
import io
import json
import math
import subprocess
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import httpx
import pytest
import shapefile as pyshp

from tests.fleet.procs import BIN, ROOT, start_api
from tests.support import SEED001_CAL, feature, machine_body

LON0, LAT0 = 112.32, 32.13
DLON = 1.0 / (111_320.0 * math.cos(math.radians(LAT0)))  # degrees per metre east
DLAT = 1.0 / 110_900.0  # degrees per metre north
# an L (120 m x 100 m less a 60 m x ~48 m corner) with a slanted inner edge: ~0.9 ha, so the
# ISO 11783 integer m^2 of the TimeLog totals are exact to 0.01 %
L_FIELD = {
    "type": "Polygon",
    "coordinates": [
        [
            [LON0 + x * DLON, LAT0 + y * DLAT]
            for x, y in [(0, 0), (120, 0), (120, 50), (60, 56), (60, 100), (0, 100), (0, 0)]
        ]
    ],
}
REL = 1e-4  # 0.01 %


def _same(values: dict[str, float], rel: float = REL) -> None:
    """Every reading of one quantity equals the first within ``rel``."""
    ref_name, ref = next(iter(values.items()))
    for name, v in values.items():
        assert v == pytest.approx(ref, rel=rel), f"{name} = {v} but {ref_name} = {ref}"


def _shp_records(data: bytes, folder: str = "") -> list[dict]:
    z = zipfile.ZipFile(io.BytesIO(data))
    base = [n for n in z.namelist() if n.endswith(".shp") and n.startswith(folder)][0][:-4]
    r = pyshp.Reader(
        shp=io.BytesIO(z.read(base + ".shp")),
        shx=io.BytesIO(z.read(base + ".shx")),
        dbf=io.BytesIO(z.read(base + ".dbf")),
    )
    return [rec.as_dict() for rec in r.records()]


def _taskdata(data: bytes) -> ET.Element:
    z = zipfile.ZipFile(io.BytesIO(data))
    name = next(n for n in z.namelist() if n.upper().endswith("TASKDATA.XML"))
    return ET.fromstring(z.read(name))


def _build(c: httpx.Client) -> dict:
    """Field, machine, plan, a prescription with two edits, a sent job."""
    field = c.post("/api/v1/fields", json=feature(L_FIELD, name="L field"))
    assert field.status_code == 201, field.text
    field = field.json()
    cal = {**SEED001_CAL, "min_rpm": 10.0}  # 220..300 kg/ha meterable at 6 m, 0.8..2.5 m/s
    m = c.post("/api/v1/machines", json=machine_body("sim", 6.0, calibration=cal)).json()
    plan = c.post(
        f"/api/v1/fields/{field['id']}/plans",
        json={"swath_width_m": 6.0, "cell_length_m": 10.0, "headland_passes": 1},
    )
    assert plan.status_code == 201, plan.text
    plan = plan.json()
    rx = c.post(
        f"/api/v1/plans/{plan['id']}/prescriptions",
        json={"model": "uniform", "params": {"rate_kg_ha": 260.0}, "machine_id": m["id"]},
    )
    assert rx.status_code == 201, rx.text
    rx = rx.json()
    n = plan["n_cells"]
    for edit in (
        [{"seq": s, "rate_kg_ha": 300.0} for s in range(0, n, 3)],
        [{"seq": s, "rate_kg_ha": 220.0} for s in range(1, n, 4)],
    ):
        r = c.post(f"/api/v1/prescriptions/{rx['id']}/edits", json={"cells": edit})
        assert r.status_code == 201, r.text
    job = c.post("/api/v1/jobs", json={"prescription_id": rx["id"], "machine_id": m["id"]})
    assert job.status_code == 201, job.text
    job = job.json()
    sent = c.post(f"/api/v1/jobs/{job['id']}/state", json={"state": "sent"})
    assert sent.status_code == 200, sent.text
    token = c.post(f"/api/v1/machines/{m['id']}/device-token").json()["token"]
    return {"field": field, "plan": plan, "rx": rx, "job": job, "token": token}


def _drive(url: str, built: dict, tmp_path: Path) -> None:
    dev = {"Authorization": f"Bearer {built['token']}"}
    pkg = httpx.get(f"{url}/api/v1/device/jobs/{built['job']['id']}/package", headers=dev)
    assert pkg.status_code == 200, pkg.text
    (tmp_path / "job.json").write_bytes(pkg.content)
    out = subprocess.run(
        [str(BIN / "fieldrx-edge"), "simulate", str(tmp_path / "job.json"), "--server", url,
         "--token", built["token"], "--json", "--seed", "2",
         "--state-dir", str(tmp_path / "state"), "--compare-runs", "1"],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    sim = json.loads(out.stdout.strip().splitlines()[-1])
    assert sim["telemetry_drained"] is True and sim["job_state_reported"] is True


def _read_everything(c: httpx.Client, built: dict) -> dict:
    rx_id, job_id = built["rx"]["id"], built["job"]["id"]
    out: dict = {"field": c.get(f"/api/v1/fields/{built['field']['id']}").json()}
    out["rx"] = c.get(f"/api/v1/prescriptions/{rx_id}").json()
    out["report"] = c.get(f"/api/v1/jobs/{job_id}/report").json()
    out["summary"] = c.get(f"/api/v1/jobs/{job_id}/summary").json()
    for fmt, profile in (("geojson", "cells"), ("shapefile", "cells"), ("isoxml", "cells"),
                         ("isoxml-zones", "cells"), ("shapefile", "deere")):  # fmt: skip
        r = c.get(f"/api/v1/prescriptions/{rx_id}/export?format={fmt}&profile={profile}")
        assert r.status_code == 200, r.text
        out[f"rx_{fmt}_{profile}"] = r.content
    for fmt in ("csv", "shapefile", "isoxml"):
        r = c.get(f"/api/v1/jobs/{job_id}/export?format={fmt}&background=false")
        assert r.status_code == 200, r.text
        out[f"job_{fmt}"] = r.content
    return out


def test_one_set_of_numbers_on_every_screen_and_file(
    database_url,  # noqa: ANN001
    org,  # noqa: ANN001
    tmp_path: Path,
) -> None:
    api, url = start_api(database_url)
    try:
        c = httpx.Client(base_url=url, headers=org.headers(), timeout=120)
        built = _build(c)
        _drive(url, built, tmp_path)
        assert c.get(f"/api/v1/jobs/{built['job']['id']}").json()["state"] == "completed"
        got = _read_everything(c, built)
    finally:
        api.stop()
    rx, rep, summ = got["rx"], got["report"], got["summary"]
    ver = rx["summary"]
    field_area = got["field"]["properties"]["area_m2"]
    assert rx["current_version"] == 3
    report_cells = sum(x["area_m2"] for x in rep["cells"])
    print(
        f"field {field_area:.1f} m2, version cells {ver['area_m2']:.1f} m2,"
        f" report cells {report_cells:.1f} m2; planned {ver['product_kg']:.3f} kg (version)"
        f" {rep['planned_total_kg']:.3f} kg (report); applied {rep['applied_total_kg']:.3f} kg"
        f" over {rep.get('applied_area_m2', 0):.1f} m2"
    )
    # the report's cells are the version's cells, inside the field
    assert report_cells <= field_area * (1 + 1e-9), (report_cells, field_area)
    assert rep["planned_total_kg"] == pytest.approx(ver["product_kg"], rel=REL)

    # the field's area: the field screen, the plan, the report, the partfields
    rx_iso = _taskdata(got["rx_isoxml_cells"])
    zones_iso = _taskdata(got["rx_isoxml-zones_cells"])
    job_iso = _taskdata(got["job_isoxml"])
    _same({
        "field": field_area,
        "report": rep["field_area_m2"],
        "summary": summ["field_area_ha"] * 1e4,
        "rx ISOXML grid PFD": float(rx_iso.find("PFD").get("D")),
        "rx ISOXML zones PFD": float(zones_iso.find("PFD").get("D")),
        "as-applied ISOXML PFD": float(job_iso.find("PFD").get("D")),
    })  # fmt: skip

    # the version's area and planned amount (every cell is prescribed, rate > 0)
    gj = json.loads(got["rx_geojson_cells"])["features"]
    gj_area = sum(f["properties"]["area_m2"] for f in gj)
    gj_kg = sum(f["properties"]["rate_kg_ha"] * f["properties"]["area_m2"] for f in gj) / 1e4
    shp = _shp_records(got["rx_shapefile_cells"])
    shp_area = sum(r["AREA_M2"] for r in shp)
    shp_kg = sum(r["RATE"] * r["AREA_M2"] for r in shp) / 1e4
    job_rows = list(csv.DictReader(io.StringIO(got["job_csv"].decode())))
    csv_area = sum(float(r["area_m2"]) for r in job_rows)
    csv_planned = sum(float(r["target_rate_kg_ha"]) * float(r["area_m2"]) for r in job_rows) / 1e4
    job_shp = _shp_records(got["job_shapefile"])
    jshp_planned = sum(r["TARGET"] * r["AREA_M2"] for r in job_shp) / 1e4
    _same({
        "prescription screen": ver["area_m2"],
        "GeoJSON": gj_area,
        "Shapefile": shp_area,
        "job report": rep["planned_area_m2"],
        "job summary": summ["planned_area_ha"] * 1e4,
        "as-applied CSV": csv_area,
    })  # fmt: skip
    _same({
        "prescription screen": ver["product_kg"],
        "GeoJSON": gj_kg,
        "Shapefile": shp_kg,
        "job report": rep["planned_total_kg"],
        "job summary / print": summ["planned_total_kg"],
        "as-applied CSV": csv_planned,
        "as-applied Shapefile": jshp_planned,
    })  # fmt: skip
    # no sum of cell areas exceeds the field
    sums = {"version": ver["area_m2"], "GeoJSON": gj_area, "Shapefile": shp_area,
            "report": report_cells, "CSV": csv_area}  # fmt: skip
    for name, a in sums.items():
        assert a <= field_area * (1 + 1e-9), f"{name}: cells {a} m2 > field {field_area} m2"

    # applied amount and area: report, summary, CSV, Shapefile, the TimeLog task totals
    tim = {d.get("A"): float(d.get("B")) for d in job_iso.find("TSK").find("TIM").findall("DLV")}
    applied_cells = [r for r in job_rows if float(r["m2_g"]) > 0]
    _same({
        "report": rep["applied_total_kg"],
        "summary / print": summ["applied_total_kg"],
        "ISOXML TIM DDI 352": tim["0160"] / 1000.0,
        "CSV (cells + outside)": sum(float(r["m2_g"]) for r in job_rows) / 1000.0
        + rep["applied_outside_cells_kg"],
    })  # fmt: skip
    _same({
        "report": rep["applied_area_m2"],
        "summary / print": summ["area_applied_ha"] * 1e4,
        "ISOXML TIM DDI 116": tim["0074"],
        "CSV": sum(float(r["area_m2"]) for r in applied_cells),
        "Shapefile": sum(r["AREA_M2"] for r in job_shp if r["M2_G"] > 0),
    })  # fmt: skip
    never = [r for r in job_rows if float(r["m2_g"]) == 0 and float(r["target_rate_kg_ha"]) > 0]
    never_kg = sum(float(r["target_rate_kg_ha"]) * float(r["area_m2"]) for r in never) / 1e4
    assert rep["never_applied_kg"] == pytest.approx(never_kg, rel=REL, abs=1e-6)
    assert summ["never_applied_kg"] == pytest.approx(rep["never_applied_kg"], rel=REL, abs=1e-6)
    assert rep["applied_area_m2"] <= field_area
    # the report's headline (target vs applied) is the same two amounts
    assert rep["outcome"]["target_kg"] == pytest.approx(rep["planned_total_kg"], rel=REL)
    assert rep["outcome"]["applied_kg"] == pytest.approx(rep["applied_in_cells_kg"], rel=REL)
    # the job applied what was planned: the figures above compare like with like
    assert rep["applied_total_kg"] == pytest.approx(rep["planned_total_kg"], rel=0.05)
