"""Every third-party TASKDATA set in ``../shared/taskdata`` gives what its README states.

The sets come from the test suites of dev4Agriculture/isoxml-dotnet and
Josephinum-Research/isoxml-py (both Apache-2.0; licence and commit beside the data);
the values asserted here are the ones those libraries' own tests assert
(``TLGTest.cs``, ``IsoGridTests.cs``), as listed in the README there.
"""

from __future__ import annotations

import datetime as dt
import re
from pathlib import Path

import numpy as np
import pytest
from fieldrx.formats import FormatError
from fieldrx.formats.archive import read_zip
from fieldrx.formats.isoxml_import import read_taskdata

from tests.support.plans import API


def _shared() -> Path | None:
    """``../shared/taskdata`` of the checkout, or of a folder above it (worktrees)."""
    for up in Path(__file__).resolve().parents[2:5]:
        cand = up.parent / "shared" / "taskdata"
        if cand.is_dir():
            return cand
    return None


SHARED = _shared()
pytestmark = pytest.mark.skipif(SHARED is None, reason="no ../shared/taskdata beside the checkout")
NOT_DATA = {"LICENSE", "COMMIT", "info.md"}


def files_of(rel: str) -> dict[str, bytes]:
    assert SHARED is not None
    d = SHARED / rel
    return {
        str(p.relative_to(d)): p.read_bytes()
        for p in d.rglob("*")
        if p.is_file() and p.name not in NOT_DATA
    }


def read(rel: str, **kw) -> object:
    return read_taskdata(files_of(rel), **kw)


# --- isoxml-dotnet -----------------------------------------------------------------------


def test_valid_timelogs():
    ds = read("isoxml-dotnet/TimeLogs/ValidTimeLogs")
    assert len(ds.timelogs) == 21
    assert [t for t in ds.timelogs if "error" in t] == []  # 0 messages
    by = {t["timelog"]: t for t in ds.timelogs}
    one = by["TLG00001"]
    assert "141" in one["reported"] and "1000" not in one["reported"]
    assert one["records"] == 4716
    assert one["reported"]["141"] == 4716 and one["reported"]["148"] == 560
    assert by["TLG00002"]["totals"]["90"]["total"] == 242461  # yield total mass, no resets
    # a harvester's logs: no applied rate, and the preview says what they can give
    assert not one["has_rate"] and "no application accuracy" in one["gives"]


def test_timelog_second_entry_date():
    from fieldrx.formats.timelog import read_timelog

    d = SHARED / "isoxml-dotnet/TimeLogs/ValidTimeLogs"  # type: ignore[operator]
    log = read_timelog(
        "TLG00001", (d / "TLG00001.xml").read_bytes(), (d / "TLG00001.bin").read_bytes()
    )
    assert len(log) == 4716
    assert dt.datetime.fromtimestamp(log.t[1], dt.UTC).date() == dt.date(2020, 1, 2)


@pytest.mark.parametrize(("rel", "layers"), [("Grid/Type1", 1), ("Grid/Type2", 3)])
def test_grids_without_partfield_still_checked(rel, layers):
    ds = read(f"isoxml-dotnet/{rel}")
    (sk,) = [s for s in ds.skipped if "TSK" in s["what"]]
    assert "has no boundary" in sk["why"]
    assert f"{layers} layer" in sk["why"] and "was read and is whole" in sk["why"]


@pytest.mark.parametrize("rel", ["Grid/Type1_Invalid", "Grid/Type2_Invalid"])
def test_invalid_grids_give_one_message(rel):
    with pytest.raises(FormatError) as exc:
        read(f"isoxml-dotnet/{rel}")
    msg = str(exc.value)
    assert "GRD00001.BIN has" in msg and msg.count("GRD00001.BIN has") == 1


def test_grid_read_value():
    ds = read("isoxml-dotnet/Grid/Type2_ReadValue")
    (rx,) = ds.prescriptions
    assert rx.ddi == 6 and rx.kind == "grid type 2"
    got = rx.rates_at(np.array([7.2251319728, 8.2251319728]), np.array([52.2240239571] * 2))
    # 1005 mg/m^2 = 10.05 kg/ha; outside the grid the task's default zone (rate 0)
    assert got[0] == pytest.approx(10.05) and got[1] == rx.default_rate_kg_ha == 0.0


@pytest.mark.parametrize("rel", ["LinkList/ValidLinkList", "ExternalFiles/MultipleExternals"])
def test_split_sets_read(rel):
    ds = read(f"isoxml-dotnet/{rel}")
    assert len(ds.fields) == 1


@pytest.mark.parametrize(
    ("name", "fields", "timelogs"),
    [("ZippedTaskWithSubFolder.zip", 0, 0), ("MultiSubFolder.zip", 3, 1)],
)
def test_archives_with_sub_folders(name, fields, timelogs):
    data = (SHARED / "isoxml-dotnet/LoadFromStream" / name).read_bytes()  # type: ignore[operator]
    ds = read_taskdata(read_zip(data))
    assert (len(ds.fields), len(ds.timelogs)) == (fields, timelogs)


def test_invalid_xml_and_archive_refused():
    with pytest.raises(FormatError, match=r"TASKDATA.XML: malformed XML \(.*line 3"):
        read("isoxml-dotnet/Structure/InvalidXML")
    data = (SHARED / "isoxml-dotnet/LoadFromStream/InvalidArchive.zip").read_bytes()  # type: ignore[operator]
    with pytest.raises(FormatError, match="no TASKDATA.XML in the upload"):
        read_taskdata(read_zip(data))


# --- isoxml-py ---------------------------------------------------------------------------


def test_volume_grid_needs_and_takes_a_density():
    ds = read("isoxml-py/v3/grid_type_2")
    (sk,) = [s for s in ds.skipped if s["needs_density"]]
    assert "l/ha" in sk["why"] and "density" in sk["why"]
    ds = read("isoxml-py/v3/grid_type_2", density_kg_l=1.2)
    (rx,) = ds.prescriptions
    assert rx.unit == "l/ha" and rx.density_kg_l == 1.2 and rx.kind == "grid type 2"
    plain = read("isoxml-py/v3/grid_type_2", density_kg_l=1.0).prescriptions[0]
    np.testing.assert_allclose(rx.grid["rates"], plain.grid["rates"] * 1.2)


@pytest.mark.parametrize(
    ("rel", "zones", "lo", "hi"),
    [
        ("v4/farmdoc/fertilizer_map_1", 32, 137, 198),
        ("v4/farmdoc/fertilizer_map_2", 6, None, None),
        ("v4/deutz_export", 31, None, None),
    ],
)
def test_zone_maps(rel, zones, lo, hi):
    (rx,) = read(f"isoxml-py/{rel}").prescriptions
    assert rx.kind == "zones" and len(rx.zones) == zones
    rates = [r for r, _ in rx.zones]
    if lo is not None:
        assert round(min(rates)) == lo and round(max(rates)) == hi


@pytest.mark.parametrize(
    "rel", ["v4/cnh_export", "v4/farmdoc/field_export", "v4/farmdoc/seeding", "v4/full_task"]
)
def test_field_sets(rel):
    ds = read(f"isoxml-py/{rel}")
    assert len(ds.fields) == 1 and not ds.prescriptions
    if rel.endswith("seeding"):  # seeds per m^2 have no kg/ha: said so
        assert any("count" in s["why"].lower() or "DDI 6" in s["why"] for s in ds.skipped)


# --- through the API ---------------------------------------------------------------------


def _post(client, h, files: dict[str, bytes], **q):
    up = [("files", (k.replace("/", "_"), v, "application/octet-stream")) for k, v in files.items()]
    qs = "&".join(f"{k}={v}" for k, v in q.items())
    return client.post(f"{API}/imports/isoxml?{qs}", headers=h, files=up)


def _count(client, h, what: str) -> int:
    body = client.get(f"{API}/{what}?limit=500", headers=h).json()
    return body["total"] if "total" in body else len(body["items"])


def test_fertilizer_map_is_a_full_prescription_and_reimport_matches(client, org):
    h = org.headers()
    files = files_of("isoxml-py/v4/farmdoc/fertilizer_map_1")
    pre = _post(client, h, files)
    assert pre.status_code == 200, pre.text
    body = pre.json()
    (p,) = body["preview"]["prescriptions"]
    assert p["min_rate_kg_ha"] == pytest.approx(137, abs=0.5)
    assert p["max_rate_kg_ha"] == pytest.approx(198, abs=0.5)
    assert p["distance_m"] == 0 and p["overlap_pct"] > 50
    ok = _post(client, h, files, confirm=body["sha256"])
    assert ok.status_code == 201, ok.text
    created = ok.json()["created"]
    rx_id = created["prescriptions"][0]["id"]
    rx = client.get(f"{API}/prescriptions/{rx_id}", headers=h).json()
    s = rx["summary"]
    # the field's 1.715 ha at 137-198 kg/ha: the screen's figures, legend and zones
    # table, not zeros (the writer declares 17,137 m2)
    assert s["area_m2"] == pytest.approx(17137, rel=0.01)
    assert 137 <= s["rate_min_kg_ha"] <= s["rate_max_kg_ha"] <= 198.5
    assert s["product_kg"] == pytest.approx(s["rate_mean_kg_ha"] * s["area_ha"], rel=1e-3)
    assert len(s["classes"]["breaks_kg_ha"]) == 7 and s["classes"]["table"]
    assert 0 <= s["imported_outside"]["share_pct"] < 20
    assert len(s["extent"]) == 4
    n_farms, n_fields = _count(client, h, "farms"), _count(client, h, "fields")
    # the same set again: the farm and the field are found, nothing is created twice
    again = _post(client, h, files).json()
    assert again["preview"]["farms"][0]["match"]["by"] == "name"
    assert again["preview"]["fields"][0]["match"]["id"] == created["fields"][0]["id"]
    ok2 = _post(client, h, files, confirm=again["sha256"])
    assert ok2.status_code == 201, ok2.text
    c2 = ok2.json()["created"]
    assert c2["farms"] == [] and c2["fields"] == []
    assert (_count(client, h, "farms"), _count(client, h, "fields")) == (n_farms, n_fields)


def test_grid_elsewhere_flagged_before_anything_is_stored(client, org):
    h = org.headers()
    files = files_of("isoxml-dotnet/Grid/Type2_ReadValue")
    xml = files["TASKDATA.XML"].decode("utf-8-sig")
    # the partfield moved 30 degrees east (near Moscow); the grid stays in Lower Saxony
    moved = re.sub(r'(<PNT A="2" C="[0-9.]+" D=")7\.', r"\g<1>37.", xml)
    files["TASKDATA.XML"] = moved.encode()
    n_fields = _count(client, h, "fields")
    pre = _post(client, h, files)
    assert pre.status_code == 200, pre.text
    body = pre.json()["preview"]
    assert body["prescriptions"] == []
    (bad,) = body["bad"]
    assert "TSK[TSK1]" in bad["what"] and "does not overlap" in bad["why"]
    km = float(re.search(r"lies ([0-9,.]+) km", bad["why"]).group(1).replace(",", ""))
    assert 1900 < km < 2200
    assert _count(client, h, "fields") == n_fields  # the preview stored nothing


def test_logs_elsewhere_flagged_and_refused_before_anything_is_stored(client, org):
    from tests.support.plans import make_field, make_plan
    from tests.support.prescriptions import make_rx

    h = org.headers()
    fid = make_field(client, h)  # seed 001's plot in Hubei, China
    plan = make_plan(client, h, fid, swath_width_m=4, cell_length_m=5)
    rx = make_rx(client, h, plan["id"], model="uniform", params={"rate_kg_ha": 150})
    d = SHARED / "isoxml-dotnet/TimeLogs/ValidTimeLogs"  # type: ignore[operator]
    up = [
        ("files", (n, (d / n).read_bytes(), "application/octet-stream"))
        for n in ("TLG00001.xml", "TLG00001.bin")
    ]
    machines = _count(client, h, "machines")
    url = f"{API}/imports/timelog?prescription_id={rx['id']}&width_m=6"
    pre = client.post(url, headers=h, files=up)
    assert pre.status_code == 200, pre.text
    body = pre.json()
    (tl,) = body["timelogs"]
    assert tl["placement"]["on_field"] == 0 and tl["placement"]["distance_m"] > 7_000_000
    (why,) = body["refused"]
    assert "TLG00001: no record lies on the prescription's field" in why and " km away" in why
    # a harvester's log: it says what it can and cannot give
    assert not tl["has_rate"] and "coverage map" in tl["gives"]
    r = client.post(f"{url}&confirm={body['sha256']}", headers=h, files=up)
    assert r.status_code == 422 and "nothing stored" in r.json()["detail"]
    assert _count(client, h, "machines") == machines
    jobs = client.get(f"{API}/jobs?limit=500", headers=h).json()
    assert not [j for j in jobs.get("items", []) if j.get("prescription_id") == rx["id"]]
