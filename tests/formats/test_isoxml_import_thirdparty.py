"""Import of TASKDATA sets written by other software (see tests/formats/data/README.md)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import shapely
from fieldrx.formats.isoxml_import import read_taskdata
from pyproj import Geod

from tests.support.plans import API

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
    assert "TSK[TSK1] Task 1" in whats and "without treatment zones" in whats
    # the guidance line, the sampling route (LSG A=4) and the entry (PNT A=3) are kept
    kept = [(x["properties"]["kind"], x["properties"]["type"], x["properties"]["name"],
             x["geometry"]["type"]) for x in field.features]  # fmt: skip
    assert kept == [
        ("guidance", "guidance pattern", "GuidancePattern", "LineString"),
        ("line", "sampling route", "Outer line", "LineString"),
        ("point", "field access", "Entry", "Point"),
    ]


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
    # the guidance line, sampling route and entry point are kept with the field
    ann = client.get(f"{API}/fields/{fid}/annotations", headers=h).json()
    assert ann["source_ref"] == "ISOXML PFD2"
    assert [a["properties"]["kind"] for a in ann["features"]] == ["guidance", "line", "point"]
    assert ann["features"][2]["geometry"]["type"] == "Point"


# --- isoxml-dotnet's partfield set (GreenDB): 13 boundaries, two with holes -----------------

PARTFIELDS = Path(__file__).parent / "data" / "isoxml-dotnet_partfields" / "TASKDATA.XML"
GEOD = Geod(ellps="WGS84")


def _geod_area(g) -> float:
    """Ellipsoidal area; rings oriented first (pyproj sums signed ring areas)."""
    return abs(GEOD.geometry_area_perimeter(shapely.orient_polygons(g))[0])


def test_partfields_with_holes_areas_match_the_declared():
    ds = read_taskdata({"TASKDATA.XML": PARTFIELDS.read_bytes()})
    assert ds.version == "4.3"
    assert len(ds.fields) == 13 and not ds.prescriptions
    for f in ds.fields:
        assert f.boundary.is_valid, f.name
        # PFD D is the writer's own area (m^2, whole hundreds): within 1 %
        assert _geod_area(f.boundary) == pytest.approx(f.declared_area_m2, rel=0.01), f.name
    holed = {f.name: f.boundary for f in ds.fields if f.boundary.interiors}
    assert sorted(holed) == ["MW_LaConc_EC_Equator_Hole", "NM_Oxted_NullMeridian_Hole"]
    oxted = holed["NM_Oxted_NullMeridian_Hole"]
    (hole,) = oxted.interiors
    # the inner ring as written (LSG A=2, 11 points, lon D / lat C), first = last
    assert len(hole.coords) == 11 and hole.coords[0] == (0.000429, 51.240845)
    assert hole.coords[4] == (0.000408, 51.239528)
    # the hole is subtracted: the declared 35,600 m2 is the outer ring (45,700) less ~10,070
    outer = _geod_area(shapely.Polygon(oxted.exterior))
    assert outer > 1.25 * 35600 and _geod_area(oxted) == pytest.approx(35600, rel=0.01)
    assert not oxted.contains(shapely.Point(0.0004, 51.2402))  # inside the hole
    assert oxted.contains(shapely.Point(0.0020, 51.2395))
    eq = holed["MW_LaConc_EC_Equator_Hole"]  # straddles the equator: latitudes of both signs
    assert eq.bounds[1] < 0 < eq.bounds[3] and len(eq.interiors[0].coords) == 6
    whats = " | ".join(s["what"] + " -> " + s["why"] for s in ds.skipped)
    assert whats.count("without treatment zones") == 13


def test_partfields_with_holes_imported_through_api(client, org):
    h = org.headers()
    files = {"files": ("TASKDATA.XML", PARTFIELDS.read_bytes(), "application/xml")}
    pre = client.post(f"{API}/imports/isoxml", headers=h, files=files)
    assert pre.status_code == 200, pre.text
    body = pre.json()
    assert len(body["preview"]["fields"]) == 13
    ok = client.post(f"{API}/imports/isoxml?confirm={body['sha256']}", headers=h, files=files)
    assert ok.status_code == 201, ok.text
    by_name = {}
    for f in ok.json()["created"]["fields"]:
        got = client.get(f"{API}/fields/{f['id']}", headers=h).json()
        by_name[got["properties"]["name"]] = got
    assert len(by_name) == 13
    oxted = by_name["NM_Oxted_NullMeridian_Hole"]
    geom = shapely.geometry.shape(oxted["geometry"])
    assert len(shapely.get_parts(geom)) == 1 and len(shapely.get_parts(geom)[0].interiors) == 1
    assert oxted["properties"]["area_m2"] == pytest.approx(35600, rel=0.01)


def _holes_as_own_plns(xml: str) -> str:
    """Each hole moved into a PLN A=1 of its own holding only the interior ring, as some
    terminals export them."""
    return re.sub(
        r"(</LSG>)\s*(<LSG A=\"2\".*?</LSG>)\s*</PLN>",
        r'\1</PLN><PLN A="1">\2</PLN>',
        xml,
        flags=re.S,
    )


def test_holes_written_as_separate_polygons_attach_to_their_partfield():
    xml = PARTFIELDS.read_text()
    split = _holes_as_own_plns(xml)
    assert split.count('<PLN A="1">') == xml.count('<PLN A="1">') + 2
    ref = {f.name: f.boundary for f in read_taskdata({"TASKDATA.XML": xml.encode()}).fields}
    ds = read_taskdata({"TASKDATA.XML": split.encode()})
    assert not [s for s in ds.skipped if s["bad"]]
    got = {f.name: f.boundary for f in ds.fields}
    for name in ("NM_Oxted_NullMeridian_Hole", "MW_LaConc_EC_Equator_Hole"):
        g = got[name]
        assert isinstance(g, shapely.Polygon) and len(g.interiors) == 1, name
        outer = _geod_area(shapely.Polygon(g.exterior))
        hole = _geod_area(shapely.Polygon(g.interiors[0]))
        # exterior minus hole, within 0.01 %, and the same polygon as written in one PLN
        assert _geod_area(g) == pytest.approx(outer - hole, rel=1e-4), name
        assert shapely.equals(g, ref[name]), name


def test_one_bad_partfield_is_named_and_the_others_import(client, org):
    h = org.headers()
    # PFD3's boundary crosses itself (two points swapped): a bow-tie
    xml = PARTFIELDS.read_text()
    m = re.search(r'<PFD A="PFD3".*?</PFD>', xml, flags=re.S)
    assert m is not None
    pts = re.findall(r"<PNT [^>]*/>", m.group(0))
    bow = m.group(0).replace(pts[1], "@@").replace(pts[2], pts[1]).replace("@@", pts[2])
    bad_xml = xml.replace(m.group(0), bow).encode()
    files = {"files": ("TASKDATA.XML", bad_xml, "application/xml")}
    pre = client.post(f"{API}/imports/isoxml", headers=h, files=files)
    assert pre.status_code == 200, pre.text
    body = pre.json()
    (bad,) = body["preview"]["bad"]
    assert "PFD3" in bad["what"] and "refused" in bad["why"] and "invalid boundary" in bad["why"]
    assert len(body["preview"]["fields"]) == 12
    ok = client.post(f"{API}/imports/isoxml?confirm={body['sha256']}", headers=h, files=files)
    assert ok.status_code == 201, ok.text
    created = ok.json()["created"]
    assert len(created["fields"]) == 12
    assert [s["what"] for s in created["skipped"]] == [bad["what"]]
