"""Other terminals' as-applied Shapefile/CSV with attribute mapping."""

from __future__ import annotations

import io
import zipfile

import pytest

from tests.formats.test_asapplied_export import driven  # noqa: F401  (fixture)
from tests.support.plans import API


def _points_zip(client, h, job_id) -> bytes:
    r = client.get(f"{API}/jobs/{job_id}/export?format=shapefile", headers=h)
    z = zipfile.ZipFile(io.BytesIO(r.content))
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as o:
        for n in z.namelist():
            if "_points." in n:
                o.writestr(n.replace(f"job{job_id}_as_applied_points", "asapplied"), z.read(n))
    return out.getvalue()


def _post(client, h, rx_id, name, data, **q):
    qs = "&".join(f"{k}={v}" for k, v in {"prescription_id": rx_id, **q}.items())
    return client.post(
        f"{API}/imports/as-applied-table?{qs}", headers=h, files={"file": (name, data, "x/y")}
    )


def test_points_shapefile_round_trip(client, org, driven):  # noqa: F811
    fx, recs = driven
    h = org.headers()
    data = _points_zip(client, h, fx.job_id)
    pre = _post(client, h, fx.prescription_id, "asapplied.zip", data).json()
    assert pre["suggested"]["rate_column"] == "APPLIED" and pre["rows"] == len(recs)
    assert pre["suggested"]["time_column"] == "TIME" and "APPLIED" in pre["numeric"]
    assert pre["suggested"]["work_state_column"] == "DOWN"
    q = {"rate_column": "APPLIED", "target_column": "TARGET", "speed_column": "SPEED_MS",
         "time_column": "TIME", "work_state_column": "DOWN"}  # fmt: skip
    mapped = _post(client, h, fx.prescription_id, "asapplied.zip", data, **q).json()
    assert mapped["mapping"]["records"] == len(recs)
    ok = _post(client, h, fx.prescription_id, "asapplied.zip", data, **q,
               confirm=pre["sha256"], width_m=3)  # fmt: skip
    assert ok.status_code == 201, ok.text
    job = ok.json()["created"]["job_id"]
    rep = client.get(f"{API}/jobs/{job}/report", headers=h).json()
    orig = client.get(f"{API}/jobs/{fx.job_id}/report", headers=h).json()
    for a, b in zip(rep["cells"], orig["cells"], strict=True):
        assert a["n_records"] == b["n_records"]
        if b["mean_applied_rate_kg_ha"] is not None:
            assert a["mean_applied_rate_kg_ha"] == pytest.approx(
                b["mean_applied_rate_kg_ha"], abs=0.01
            )
    assert rep["time_worked_s"] == pytest.approx(orig["time_worked_s"], abs=0.01)


def test_csv_with_units_and_no_times(client, org, driven):  # noqa: F811
    fx, recs = driven
    h = org.headers()
    lines = ["Longitude;Latitude;N_lbac;note"]
    lines += [f"{r['lon']};{r['lat']};{r['applied_rate_kg_ha'] / 1.12085:.4f};x" for r in recs]
    data = ("\n".join(lines) + "\n").encode()
    pre = _post(client, h, fx.prescription_id, "log.csv", data).json()
    assert pre["suggested"]["lon_column"] == "Longitude" and pre["suggested"]["rate_column"] is None
    q = {"rate_column": "N_lbac", "unit": "lb/ac", "lon_column": "Longitude",
         "lat_column": "Latitude", "interval_s": 0.1}  # fmt: skip
    mapped = _post(client, h, fx.prescription_id, "log.csv", data, **q).json()
    want = sum(r["applied_rate_kg_ha"] for r in recs) / len(recs)
    assert mapped["mapping"]["mean_applied_rate_kg_ha"] == pytest.approx(want, abs=0.01)
    assert "every 0.1 s" in mapped["mapping"]["times"]
    bad = _post(client, h, fx.prescription_id, "log.csv", data, rate_column="note",
                lon_column="Longitude", lat_column="Latitude")  # fmt: skip
    assert bad.status_code == 422 and "row 0: note='x' is not a number" in bad.json()["detail"]
    no_width = _post(client, h, fx.prescription_id, "log.csv", data, **q, confirm=pre["sha256"])
    assert no_width.status_code == 422
    ok = _post(client, h, fx.prescription_id, "log.csv", data, **q, confirm=pre["sha256"],
               width_m=3)  # fmt: skip
    assert ok.status_code == 201, ok.text
    assert ok.json()["created"]["records"] == len(recs)
