"""Import of a TASKDATA set written by other software (see tests/formats/data/README.md)."""

from __future__ import annotations

from pathlib import Path

import pytest
import shapely
from fieldrx.formats.isoxml_import import read_taskdata

from tests.plans.helpers import API

FULL_TASK = Path(__file__).parent / "data" / "isoxml-py_full_task" / "TASKDATA.XML"


def test_full_task_parsed_and_skips_explained():
    ds = read_taskdata({"TASKDATA/TASKDATA.XML": FULL_TASK.read_bytes()})
    assert ds.version == "4.2"
    assert [(f.ref, f.name) for f in ds.farms] == [("FRM1", "Meyer / Peters Farm")]
    (field,) = ds.fields
    assert field.ref == "PFD2" and field.name == "Near the Highway Subfield"
    assert field.farm_ref == "FRM1" and field.declared_area_m2 == 3334.0
    # the four boundary points as written (lat C, lon D), ring closed by the reader
    assert shapely.equals(
        field.boundary,
        shapely.Polygon(
            [(7.20001, 52.213), (7.20001, 52.216), (7.20007, 52.216), (7.20007, 52.213)]
        ),
    )
    assert not ds.prescriptions
    whats = " | ".join(s["what"] + " -> " + s["why"] for s in ds.skipped)
    assert "PFD[PFD1]" in whats and "without a boundary" in whats
    assert "GGP[0] guidance pattern GuidancePattern" in whats and "reference-line" in whats
    assert "PFD[PFD2]/LSG[0] line type 4" in whats and "PFD[PFD2]/PNT[0] point type 3" in whats
    assert "TSK[TSK1] Task 1" in whats and "without treatment zones" in whats


def test_full_task_imported_through_api(client, org):
    h = org.headers()
    files = {"files": ("TASKDATA.XML", FULL_TASK.read_bytes(), "application/xml")}
    pre = client.post(f"{API}/imports/isoxml", headers=h, files=files)
    assert pre.status_code == 200, pre.text
    body = pre.json()
    assert [f["name"] for f in body["preview"]["fields"]] == ["Near the Highway Subfield"]
    ok = client.post(f"{API}/imports/isoxml?confirm={body['sha256']}", headers=h, files=files)
    assert ok.status_code == 201, ok.text
    (fid,) = [f["id"] for f in ok.json()["created"]["fields"]]
    field = client.get(f"{API}/fields/{fid}", headers=h).json()
    farm = client.get(f"{API}/farms/{field['properties']['farm_id']}", headers=h).json()
    assert farm["name"] == "Meyer / Peters Farm"
    assert field["properties"]["area_m2"] == pytest.approx(
        body["preview"]["fields"][0]["area_m2"], rel=1e-5
    )
