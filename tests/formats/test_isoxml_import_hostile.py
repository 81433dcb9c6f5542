"""Hostile and broken TASKDATA: a clear error naming file and element."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest
import shapely
from fieldrx.agronomy.cells import CellTable
from fieldrx.formats import FormatError
from fieldrx.formats.archive import parse_xml, read_zip
from fieldrx.formats.isoxml import write_isoxml_grid
from fieldrx.formats.isoxml_import import read_taskdata, read_taskdata_zip

from tests.support.plans import API

HEAD = '<?xml version="1.0" encoding="UTF-8"?>\n'
TASKDATA = (
    '<ISO11783_TaskData VersionMajor="4" VersionMinor="3" DataTransferOrigin="1">'
    '<PFD A="PFD1" C="f" D="1"><PLN A="1"><LSG A="1">'
    '<PNT A="2" C="32.1" D="112.1"/><PNT A="2" C="32.1" D="112.101"/>'
    '<PNT A="2" C="32.101" D="112.101"/><PNT A="2" C="32.1" D="112.1"/>'
    "</LSG></PLN></PFD>{extra}</ISO11783_TaskData>"
)


def _zip(files: dict[str, bytes]) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for k, v in files.items():
            z.writestr(k, v)
    return out.getvalue()


def _grid_zip() -> bytes:
    c = CellTable.rectangle(32649, 624000.0, 3556000.0, 2, 2, 10.0, 10.0).with_rates(
        np.array([100.0, 200.0, 300.0, 400.0])
    )
    boundary = shapely.union_all(c.polygons_wgs84())
    return write_isoxml_grid(c, "g", boundary, grid_cell_m=5.0)


BILLION_LAUGHS = (
    '<?xml version="1.0"?><!DOCTYPE lolz [<!ENTITY lol "lol">'
    '<!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">'
    '<!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">]>'
    '<ISO11783_TaskData VersionMajor="4" VersionMinor="3">'
    '<CTR A="CTR1" B="&lol3;"/></ISO11783_TaskData>'
)
EXTERNAL = (
    '<?xml version="1.0"?><!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
    '<ISO11783_TaskData VersionMajor="4" VersionMinor="3"><CTR A="CTR1" B="&x;"/>'
    "</ISO11783_TaskData>"
)


@pytest.mark.parametrize("doc", [BILLION_LAUGHS, EXTERNAL], ids=["expansion", "external"])
def test_entities_refused(doc):
    with pytest.raises(FormatError, match="TASKDATA.XML: XML document type declarations"):
        read_taskdata({"TASKDATA.XML": doc.encode()})


def test_malformed_xml_names_file():
    with pytest.raises(FormatError, match="TASKDATA.XML: malformed XML"):
        read_taskdata({"TASKDATA.XML": b"<ISO11783_TaskData VersionMajor='4'><PFD></ISO"})
    with pytest.raises(FormatError, match=r"PFD\[PFD1\]/PLN\[0\]/LSG\[0\]/PNT\[1\]: attribute C"):
        read_taskdata(
            {
                "TASKDATA.XML": TASKDATA.replace('C="32.1" D="112.101"', 'C="x" D="1"')
                .format(extra="")
                .encode()
            }
        )


def test_path_traversal_refused():
    data = _zip({"../TASKDATA.XML": (HEAD + TASKDATA.format(extra="")).encode()})
    with pytest.raises(FormatError, match=r"\.\./TASKDATA.XML: archive member path leaves"):
        read_zip(data)
    with pytest.raises(FormatError, match="path traversal"):
        read_zip(_zip({"/etc/TASKDATA.XML": b"x"}))


def test_zip_bomb_stops_at_the_cap():
    data = _zip({"TASKDATA/GRD00001.BIN": b"\0" * (8 << 20)})  # 8 MB of zeros -> ~8 kB zipped
    assert len(data) < 100_000
    with pytest.raises(FormatError, match="GRD00001.BIN: declares 8388608 bytes uncompressed"):
        read_zip(data, max_member_bytes=1 << 20)
    with pytest.raises(FormatError, match="inflates to more than"):
        read_zip(
            _zip({"a.bin": b"\0" * (3 << 20), "b.bin": b"\0" * (3 << 20)}),
            max_member_bytes=4 << 20,
            max_total_bytes=5 << 20,
        )


def test_declared_1gb_binary_refused_before_reading():
    z = zipfile.ZipFile(io.BytesIO(_grid_zip()))
    xml = z.read("TASKDATA/TASKDATA.XML").decode()
    size = len(z.read("TASKDATA/GRD00001.BIN"))
    files = {
        "TASKDATA.XML": xml.replace(f'H="{size}"', 'H="1073741824"').encode(),
        "GRD00001.BIN": z.read("TASKDATA/GRD00001.BIN"),
    }
    with pytest.raises(
        FormatError,
        match=r"TSK\[TSK1\]/GRD: binary GRD00001.BIN declared as "
        r"1073741824 bytes",
    ):
        read_taskdata(files)


def test_missing_and_short_binary():
    z = zipfile.ZipFile(io.BytesIO(_grid_zip()))
    xml = z.read("TASKDATA/TASKDATA.XML")
    with pytest.raises(FormatError, match=r"TSK\[TSK1\]/GRD: file GRD00001.BIN is missing"):
        read_taskdata({"TASKDATA.XML": xml})
    short = z.read("TASKDATA/GRD00001.BIN")[:-4]
    with pytest.raises(FormatError, match=r"GRD: binary GRD00001.BIN has \d+ bytes"):
        read_taskdata({"TASKDATA.XML": xml, "GRD00001.BIN": short})


def test_unknown_ddi_task_skipped_with_reason():
    extra = (
        '<TSK A="TSK1" B="seed" E="PFD1" G="1"><TZN A="1"><PDV A="DFFF" B="5"/>'
        '<PLN A="2"><LSG A="1"><PNT A="2" C="32.1" D="112.1"/><PNT A="2" C="32.1" '
        'D="112.101"/><PNT A="2" C="32.101" D="112.101"/></LSG></PLN></TZN></TSK>'
    )
    ds = read_taskdata({"TASKDATA.XML": (HEAD + TASKDATA.format(extra=extra)).encode()})
    assert not ds.prescriptions and len(ds.fields) == 1
    (sk,) = [s for s in ds.skipped if "TSK" in s["what"]]
    assert "57343" in sk["why"] and "density" in sk["why"]


def test_no_taskdata_xml():
    with pytest.raises(FormatError, match="no TASKDATA.XML in the upload"):
        read_taskdata_zip(_zip({"x.txt": b"hi"}))


def test_parse_xml_plain():
    assert parse_xml(b"<a><b x='1'/></a>", "t.xml").find("b").get("x") == "1"


@pytest.mark.parametrize(
    "files",
    [
        {"TASKDATA.XML": BILLION_LAUGHS.encode()},
        {"TASKDATA.zip": _zip({"../../TASKDATA.XML": b"<x/>"})},
    ],
    ids=["entities", "traversal"],
)
def test_api_refuses_and_stores_nothing(client, org, files):
    h = org.headers()
    before = client.get(f"{API}/fields", headers=h).json()["total"]
    up = [("files", (k, v, "application/octet-stream")) for k, v in files.items()]
    r = client.post(f"{API}/imports/isoxml?confirm={'0' * 64}", headers=h, files=up)
    assert r.status_code == 422
    assert "TASKDATA.XML" in r.json()["detail"]
    assert client.get(f"{API}/fields", headers=h).json()["total"] == before


# -- variants that must read the same: V3, split XML (XFR), type-1 grid -------------------


def _files_of(data: bytes) -> dict[str, bytes]:
    z = zipfile.ZipFile(io.BytesIO(data))
    return {n: z.read(n) for n in z.namelist()}


def test_v3_and_split_files_read_like_v4():
    files = _files_of(_grid_zip())
    ref = read_taskdata(files)
    v3 = dict(files)
    v3["TASKDATA/TASKDATA.XML"] = files["TASKDATA/TASKDATA.XML"].replace(
        b'VersionMajor="4" VersionMinor="3"', b'VersionMajor="3" VersionMinor="3"'
    )
    got3 = read_taskdata(v3)
    assert got3.version == "3.3"
    # split: the partfield moves to PFD00001.XML, TASKDATA.XML references it with XFR
    import xml.etree.ElementTree as ET

    root = ET.fromstring(files["TASKDATA/TASKDATA.XML"])
    pfd = root.find("PFD")
    root.remove(pfd)
    ET.SubElement(root, "XFR", {"A": "PFD00001", "B": "1"})
    xfc = ET.Element("XFC")
    xfc.append(pfd)
    split = dict(files)
    split["TASKDATA/TASKDATA.XML"] = ET.tostring(root)
    split["TASKDATA/PFD00001.XML"] = ET.tostring(xfc)
    got_split = read_taskdata(split)
    for got in (got3, got_split):
        assert shapely.equals(got.fields[0].boundary, ref.fields[0].boundary)
        (rx,) = got.prescriptions
        np.testing.assert_array_equal(rx.grid["rates"], ref.prescriptions[0].grid["rates"])
    with pytest.raises(FormatError, match=r"XFR\[0\]: file PFD00001.XML is missing"):
        read_taskdata({k: v for k, v in split.items() if not k.endswith("PFD00001.XML")})


def test_type1_grid_takes_zone_rates():
    files = _files_of(_grid_zip())
    import xml.etree.ElementTree as ET

    root = ET.fromstring(files["TASKDATA/TASKDATA.XML"])
    tsk = root.find("TSK")
    grd = tsk.find("GRD")
    rows, cols = int(grd.get("F")), int(grd.get("E"))
    for code, mg in ((2, 12345), (3, 20000)):
        z = ET.SubElement(tsk, "TZN", {"A": str(code)})
        ET.SubElement(z, "PDV", {"A": "0006", "B": str(mg)})
    tsk.remove(grd)
    tsk.append(grd)
    codes = np.zeros((rows, cols), dtype=np.uint8)
    codes[: rows // 2] = 2
    codes[rows // 2 :] = 3
    grd.set("I", "1")
    grd.set("H", str(codes.size))
    del grd.attrib["J"]
    ds = read_taskdata({"TASKDATA.XML": ET.tostring(root), "GRD00001.BIN": codes.tobytes()})
    (rx,) = ds.prescriptions
    assert rx.kind == "grid type 1"
    assert rx.grid["rates"][0, 0] == pytest.approx(123.45)  # row 0 = south
    assert rx.grid["rates"][-1, -1] == pytest.approx(200.0)
