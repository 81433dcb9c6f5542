"""As-applied export: ISOXML with a TimeLog and a points + cells Shapefile."""

from __future__ import annotations

import datetime as dt
import io
import struct
import zipfile
from pathlib import Path

import numpy as np
import pytest
import shapefile
import shapely
import xmlschema
from isoxml.util.isoxml_io import isoxml_from_path

from tests.fleet.helpers import make_job, record
from tests.fleet.test_reports import OUTSIDE, T0

XSD_DIR = Path("/work/shared/isoxml-xsd")


@pytest.fixture()
def driven(client, org):
    fx = make_job(org.id, state="running", lag_s=0.0)
    recs = [record(fx, s, t=T0 + s * 0.1, cell=0) for s in range(1, 31)]
    recs += [
        record(fx, s, t=T0 + 13 + s * 0.1, cell=1, applied_rate_kg_ha=275.0, actual_shaft_rpm=33.0)
        for s in range(31, 61)
    ]
    recs += [record(fx, s, t=T0 + 26 + s * 0.1, cell=None, **OUTSIDE) for s in range(61, 66)]
    recs += [
        record(fx, s, t=T0 + 39 + s * 0.1, cell=2, implement_down=False, actual_shaft_rpm=0.0)
        for s in range(66, 86)
    ]
    r = client.post("/api/v1/telemetry", json={"records": recs}, headers=fx.device_headers)
    assert r.json()["acked_seq"] == 85
    return fx, recs


def decode_timelog(header: bytes, data: bytes) -> list[dict]:
    """ISO 11783-10 binary TimeLog, decoded from the spec (independent of the writer)."""
    import xml.etree.ElementTree as ET

    tim = ET.fromstring(header)
    ptn = tim.find("PTN")
    dlvs = [int(d.get("A"), 16) for d in tim.findall("DLV")]
    out, i = [], 0
    while i < len(data):
        ms, days = struct.unpack_from("<IH", data, i)
        i += 6
        rec = {
            "t": dt.datetime(1980, 1, 1, tzinfo=dt.UTC) + dt.timedelta(days=days, milliseconds=ms)
        }
        if ptn is not None:
            if ptn.get("A") == "":
                rec["lat"] = struct.unpack_from("<i", data, i)[0] * 1e-7
                i += 4
            if ptn.get("B") == "":
                rec["lon"] = struct.unpack_from("<i", data, i)[0] * 1e-7
                i += 4
            if ptn.get("D") == "":
                rec["status"] = data[i]
                i += 1
        (n,) = struct.unpack_from("<B", data, i)
        i += 1
        for _ in range(n):
            k, v = struct.unpack_from("<Bi", data, i)
            i += 5
            rec[dlvs[k]] = v
        out.append(rec)
    return out


def test_isoxml_as_applied_valid_and_totals(client, org, driven, tmp_path):
    fx, recs = driven
    h = org.headers("viewer")
    rep = client.get(f"/api/v1/jobs/{fx.job_id}/report", headers=h).json()
    r = client.get(f"/api/v1/jobs/{fx.job_id}/export?format=isoxml", headers=h)
    assert r.status_code == 200, r.text
    zipfile.ZipFile(io.BytesIO(r.content)).extractall(tmp_path)
    d = tmp_path / "TASKDATA"
    assert sorted(p.name for p in d.iterdir()) == ["TASKDATA.XML", "TLG00001.BIN", "TLG00001.XML"]
    xmlschema.XMLSchema(str(XSD_DIR / "ISO11783_TaskFile_V4-3.xsd")).validate(
        str(d / "TASKDATA.XML")
    )
    # the header's DLV C points at DET1 in TASKDATA.XML: a cross-file IDREF a standalone
    # validation cannot resolve; every other rule must hold
    tlg_schema = xmlschema.XMLSchema(str(XSD_DIR / "ISO11783_TimeLog_V4-3.xsd"))
    errs = [str(e.reason) for e in tlg_schema.iter_errors(str(d / "TLG00001.XML"))]
    assert all(e == "IDREF 'DET1' not found in XML document" for e in errs), errs
    # independent reader: the isoxml package
    td, refs = isoxml_from_path(d)
    task = td.tasks[0]
    assert task.time_logs[0].filename == "TLG00001"
    totals = {
        int.from_bytes(v.process_data_ddi, "big"): v.process_data_value
        for v in task.times[0].data_log_values
    }
    assert totals[352] == round(rep["applied_total_kg"] * 1000)  # g
    assert totals[119] == round(rep["time_worked_s"])
    applied_area = sum(c["area_m2"] for c in rep["cells"] if c["m2_g"] > 0)
    assert totals[116] == round(applied_area)
    assert len(refs["TLG00001"]) == (4 + 2 + 4 + 4 + 1 + 1 + 4 * 5) * len(recs)
    # the binary decodes to the records: time, position, rates in mg/m2 (= 100 x kg/ha)
    rows = decode_timelog((d / "TLG00001.XML").read_bytes(), refs["TLG00001"])
    assert len(rows) == len(recs)
    for row, rec in zip(rows, recs, strict=True):
        assert abs(row["t"].timestamp() - rec["t"]) < 0.002
        assert row["lat"] == pytest.approx(rec["lat"], abs=2e-7)
        assert row["lon"] == pytest.approx(rec["lon"], abs=2e-7)
        assert row[7] == round(rec["applied_rate_kg_ha"] * 100)
        assert row[6] == round(rec["target_rate_kg_ha"] * 100)
        assert row[141] == int(rec["implement_down"])
    # the mean applied rate of the records equals the report's record statistics
    on = [r for r in rows if r[141] == 1]
    assert np.mean([r[7] for r in on]) / 100 == pytest.approx(
        np.mean([rec["applied_rate_kg_ha"] for rec in recs if rec["implement_down"]]), abs=0.01
    )


def test_shapefile_as_applied_points_and_cells(client, org, driven):
    fx, recs = driven
    h = org.headers("viewer")
    z = zipfile.ZipFile(
        io.BytesIO(
            client.get(f"/api/v1/jobs/{fx.job_id}/export?format=shapefile", headers=h).content
        )
    )
    stem = f"job{fx.job_id}_as_applied"

    def reader(name):
        return shapefile.Reader(
            shp=io.BytesIO(z.read(f"{name}.shp")),
            shx=io.BytesIO(z.read(f"{name}.shx")),
            dbf=io.BytesIO(z.read(f"{name}.dbf")),
        )

    cells = reader(stem)
    assert cells.shapeType == shapefile.POLYGON and len(cells) == 8
    for sr in cells.iterShapeRecords():
        g = shapely.geometry.shape(sr.shape.__geo_interface__)
        assert g.is_valid and sr.record["UNIT"] == "kg/ha"
    pts = reader(f"{stem}_points")
    assert pts.shapeType == shapefile.POINT and len(pts) == len(recs)
    for sr, rec in zip(pts.iterShapeRecords(), recs, strict=True):
        assert sr.shape.points[0] == pytest.approx([rec["lon"], rec["lat"]])
        assert sr.record["APPLIED"] == pytest.approx(rec["applied_rate_kg_ha"], abs=0.005)
        assert sr.record["UNIT"] == "kg/ha" and sr.record["DOWN"] == int(rec["implement_down"])
    assert {f"{stem}_points.prj", f"{stem}.prj"} <= set(z.namelist())


def test_isoxml_export_of_a_job_without_records_is_a_clear_422(client, org):
    fx = make_job(org.id, state="running", lag_s=0.0)
    r = client.get(f"/api/v1/jobs/{fx.job_id}/export?format=isoxml", headers=org.headers())
    assert r.status_code == 422
    assert "no as-applied records" in r.json()["detail"]
    shp = client.get(f"/api/v1/jobs/{fx.job_id}/export?format=shapefile", headers=org.headers())
    assert shp.status_code == 200  # cells with zero applied, no points
