"""NMEA from real receivers (item 8): excerpts of gpsd's test logs in tests/edge/data.

Each case failed on the parser before this change: the $IN talker was dropped,
empty-time no-fix sentences were "malformed", GNS was ignored, binary bytes in
front of a sentence lost it, and out-of-range or non-finite numbers became fixes.
"""

from __future__ import annotations

import json
import math
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
from fieldrx_edge.gnss import Fix, NmeaParser, file_lines
from fieldrx_edge.sim import nmea
from hypothesis import given, settings
from hypothesis import strategies as st

DATA = Path(__file__).parent / "data"
M_PER_DEG = 111_320.0  # metres per degree of latitude (and of longitude at the equator)


def log_lines(name: str) -> list[str]:
    """A fixture's sentences, without its '#' header (gpsd's log comment convention)."""
    return [ln for ln in (DATA / name).read_text().splitlines() if not ln.startswith("#")]


def parse(lines, max_hdop: float | None = None) -> tuple[NmeaParser, list[Fix]]:  # noqa: ANN001
    p = NmeaParser(max_hdop=max_hdop)
    out: list[Fix] = []
    for ln in lines:
        out += p.feed(ln)
    return p, out + p.flush()


def nmea_deg(v: str, hemi: str, deg_digits: int) -> float:
    d = int(v[:deg_digits]) + float(v[deg_digits:]) / 60.0
    return -d if hemi in "SW" else d


def assert_finite(fx: Fix) -> None:
    names = ("t", "time_of_day_s", "lat", "lon", "hdop", "altitude_m", "speed_m_s", "course_deg")
    for name in names:
        v = getattr(fx, name)
        assert v is None or math.isfinite(v), (name, v)


# -- every talker: Humminbird $IN --------------------------------------------

# gpsd's own output for this log (test/daemon/humminbird-M37.log.chk, TPV lat/lon/speed)
GPSD_HUMMINBIRD = {
    "19:41:01": (44.435216667, -71.675993333, 2.675),  # RMC
    "19:41:03": (44.435223333, -71.675930000, 2.727),  # RMC
    "19:41:05": (44.435236667, -71.675858333, 2.727),  # RMC
    "19:41:07": (44.435248333, -71.675795000, 2.727),  # RMC
    "19:41:08": (44.435248333, -71.675758333, None),  # GGA (gpsd's speed is its own estimate)
    "19:41:12": (44.435275000, -71.675633333, None),  # GGA
}


def test_in_talker_gives_the_fixes_gpsd_gives():
    p, fixes = parse(log_lines("humminbird-m37.nmea"))
    s = p.stats
    assert s.talkers == {"IN": 12}
    assert s.sentences["RMC"] == 6 and s.sentences["GGA"] == 3
    assert s.fixes == 9 and s.no_fix == 0 and s.malformed == 0
    assert all(f.valid and f.talker == "IN" for f in fixes)
    by_time = {
        f"{int(f.time_of_day_s // 3600):02d}:{int(f.time_of_day_s % 3600 // 60):02d}:"
        f"{int(f.time_of_day_s % 60):02d}": f
        for f in fixes
    }
    for hms, (lat, lon, speed) in GPSD_HUMMINBIRD.items():
        f = by_time[hms]
        assert abs(f.lat - lat) * M_PER_DEG < 0.001  # within 1 mm of gpsd
        assert abs(f.lon - lon) * M_PER_DEG * math.cos(math.radians(lat)) < 0.001
        if speed is not None:
            assert f.speed_m_s == pytest.approx(speed, abs=0.001)
    assert by_time["19:41:08"].fix_quality == 2  # GGA DGPS
    assert by_time["19:41:01"].t == pytest.approx(1158435661.0)  # 2006-09-16T19:41:01Z


# -- no-fix start-up with an empty time field: Quectel EG25-G -----------------


def test_empty_time_no_fix_sentences_are_no_fix_not_malformed():
    p, fixes = parse(log_lines("quectel-eg25-g-coldstart.nmea"))
    s = p.stats
    assert s.malformed == 0 and s.bad_checksum == 0
    assert s.sentences == {"RMC": 5, "GGA": 5, "GNS": 5, "VTG": 5}
    # one epoch per receiver cycle: GNS carries the time, the untimed GGA/RMC join it
    assert s.fixes == 5 and s.no_fix == 3
    assert [f.valid for f in fixes] == [False, False, False, True, True]
    assert [round(f.time_of_day_s, 2) for f in fixes[:3]] == [69274.96, 69275.96, 69276.96]
    assert all(f.lat is None and f.fix_quality == 0 for f in fixes[:3])
    f = fixes[3]
    assert f.types == {"GGA", "GNS", "VTG", "RMC"}
    assert f.lat == pytest.approx(nmea_deg("3645.876324", "N", 2), abs=1e-12)
    assert f.lon == pytest.approx(nmea_deg("03124.670280", "E", 3), abs=1e-12)
    assert f.fix_quality == 1 and f.n_sats == 3 and f.hdop == 1.3
    assert f.speed_m_s == pytest.approx(1.3 * 1852 / 3600)


def test_untimed_no_fix_receiver_gives_one_epoch_per_cycle():
    # a receiver that sends only untimed no-fix GGA + RMC (no GNS) before its first fix
    lines = ["$GPGGA,,,,,,0,,,,,,,,*66", "$GPRMC,,V,,,,,,,,,,N*53"] * 4
    p, fixes = parse(lines)
    assert p.stats.malformed == 0
    assert len(fixes) == 4 and p.stats.no_fix == 4
    assert all(f.types == {"GGA", "RMC"} and not f.valid for f in fixes)


# -- GNS: a GNS + VTG receiver, and GNS mode letters -------------------------


def test_gns_vtg_receiver_gives_fixes_with_speed():
    # the Telit's own GNS and VTG sentences, as a receiver set to output only GNS + VTG sends them
    lines = [ln for ln in log_lines("telit-pls83-w.nmea") if ln[3:6] == "GNS" or ln[:6] == "$GPVTG"]
    p, fixes = parse(lines)
    assert len(lines) == 6
    assert p.stats.fixes == 3 and p.stats.no_fix == 0
    for f, t in zip(fixes, ("043539.00", "043540.00", "043541.00"), strict=True):
        assert f.valid and f.types == {"GNS", "VTG"} and f.talker == "GN"
        assert f.time_of_day_s == pytest.approx(4 * 3600 + 35 * 60 + float(t[4:]))
        assert f.fix_quality == 1 and f.n_sats == 14 and f.hdop == 1.3 and f.altitude_m == 250.8
        assert f.speed_m_s == 0.0  # from VTG, which waits to join its epoch
    assert fixes[0].lat == pytest.approx(nmea_deg("4333.190206", "N", 2), abs=1e-12)
    assert fixes[0].lon == pytest.approx(nmea_deg("00127.618380", "E", 3), abs=1e-12)


def test_multi_talker_epoch_merges_into_one_fix():
    p, fixes = parse(log_lines("telit-pls83-w.nmea"))
    s = p.stats
    assert s.talkers == {"GA": 9, "GN": 3, "GP": 9}
    assert s.fixes == 3 and s.no_fix == 0
    f = fixes[0]
    assert f.types == {"GGA", "GNS", "VTG", "RMC"}
    assert f.quality_from == "GGA" and f.n_sats == 5  # the epoch's first GGA/GNS gives quality data
    assert f.t == pytest.approx(1756960539.0)  # 2025-09-04T04:35:39Z from RMC


def test_zda_dates_a_receiver_without_rmc():
    lines = [ln for ln in log_lines("ublox-zed-f9p.nmea") if ln[3:6] in ("GGA", "ZDA")]
    p, fixes = parse(lines)
    assert len(fixes) == 2 and all(f.valid for f in fixes)
    # 2019-04-12T00:39:56Z and :57Z: the date comes from ZDA, the time of day from GGA
    assert [f.t for f in fixes] == [1555029596.0, 1555029597.0]


@pytest.mark.parametrize(
    ("mode", "quality"),
    [("RN", 4), ("FA", 5), ("DN", 2), ("AAN", 1), ("E", 6), ("NNN", 0), ("", 0)],
)
def test_gns_mode_letters_map_to_fix_quality(mode, quality):
    gns = [
        nmea.sentence(f"GNGNS,12000{i}.00,5206.0000,N,01512.0000,E,{mode},10,0.8,100.0,40.0,,,V")
        for i in range(2)
    ]
    p, fixes = parse(gns)
    assert [f.fix_quality for f in fixes] == [quality, quality]
    assert all(f.valid == (quality > 0) for f in fixes)


# -- resync on '$' after binary bytes: u-blox ZED-F9P with UBX ----------------


def ubx(cls: int, mid: int, payload: bytes) -> bytes:
    """A UBX frame: sync 0xB5 0x62, class, id, length, payload, 8-bit Fletcher checksum."""
    body = struct.pack("<BBH", cls, mid, len(payload)) + payload
    a = b = 0
    for byte in body:
        a = (a + byte) & 0xFF
        b = (b + a) & 0xFF
    return b"\xb5\x62" + body + bytes((a, b))


def nav_pvt(i: int) -> bytes:
    """A NAV-PVT frame (class 0x01, id 0x07, 92 bytes) whose payload holds '$' and '*' bytes."""
    payload = bytearray(92)
    itow = 2_400_000 + 1000 * i
    struct.pack_into("<IHBBBBBB", payload, 0, itow, 2019, 4, 12, 0, 39, 56 + i, 0x37)
    payload[20] = 3  # fixType 3D
    struct.pack_into("<ii", payload, 24, 1705000668, -458775673)  # lon, lat 1e-7 deg
    payload[40:44] = b"$*$,"  # bytes that look like NMEA framing inside the binary
    return ubx(0x01, 0x07, bytes(payload))


def test_binary_bytes_before_a_sentence_do_not_lose_it(tmp_path):
    lines = log_lines("ublox-zed-f9p.nmea")
    _, clean = parse(lines)
    raw = b"".join(nav_pvt(i) + ln.encode() + b"\r\n" for i, ln in enumerate(lines))
    log = tmp_path / "f9p-ubx.log"
    log.write_bytes(raw)
    p, fixes = parse(file_lines(log))
    s = p.stats
    assert s.sentences["RMC"] == 2 and s.sentences["GGA"] == 2 and s.sentences["VTG"] == 2
    assert s.bad_checksum == 0
    # every sentence was found behind its UBX frame; only fragments of UBX frames split
    # by their own CR/LF bytes are malformed lines
    assert s.other_sentences + 6 == len(lines)
    assert s.resync >= len(lines) - s.malformed and s.lines - len(lines) == s.malformed
    assert [(f.t, f.lat, f.lon, f.speed_m_s) for f in fixes] == [
        (f.t, f.lat, f.lon, f.speed_m_s) for f in clean
    ]
    assert all(f.valid for f in fixes) and len(fixes) == 2


def test_proprietary_query_and_unknown_sentences_are_other_not_malformed():
    lines = [
        nmea.sentence("PUBX,00,120000.00,5206.0000,N,01512.0000,E"),
        nmea.sentence("CCGPQ,GGA"),
        nmea.sentence("GPXYZ,1,2,3"),
        nmea.sentence("G*RMC,1"),
    ]
    p, fixes = parse(lines)
    assert fixes == [] and p.stats.other_sentences == 3 and p.stats.malformed == 1


def test_replay_paces_gns_lines_behind_binary_bytes(tmp_path):
    lines = [
        nmea.sentence(
            f"GNGNS,1200{i // 10:02d}.{i % 10}0,5206.0000,N,01512.0000,E,AA,10,0.8,1.0,4.0,,,V"
        )
        for i in range(11)
    ]  # 1.0 s of a 10 Hz GNS-only receiver, each line behind UBX bytes
    log = tmp_path / "gns.log"
    log.write_bytes(b"".join(b"\xb5\x62\x01\x07" + ln.encode() + b"\r\n" for ln in lines))
    t = time.monotonic()
    assert len(list(file_lines(log, speed=4.0))) == 11
    assert 0.2 <= time.monotonic() - t < 0.6  # 1 s of log at 4x


def test_bytes_after_a_checksum_and_two_sentences_on_one_line():
    lines = log_lines("ublox-zed-f9p.nmea")
    rmc, gga, rmc2 = lines[0], lines[2], lines[23]
    assert rmc2.startswith("$GNRMC,003957.00")
    p, fixes = parse([rmc + "\xb5b\x01\x07\\$\x00", gga + rmc2])
    assert p.stats.sentences["RMC"] == 2 and p.stats.sentences["GGA"] == 1
    assert p.stats.resync == 1 and p.stats.malformed == 0 and p.stats.bad_checksum == 0
    assert len(fixes) == 2 and fixes[0].types == {"RMC", "GGA"}
    pubx = nmea.sentence("PUBX,00,003958.00,4552.65403,S,17030.00668,E")
    p.feed("\xb5b\x01" + pubx)
    assert p.stats.other_sentences == 1 and p.stats.resync == 2


# -- range checks -------------------------------------------------------------


@pytest.mark.parametrize(
    ("lat", "ns", "lon", "ew"),
    [
        ("5206.0000", "N", "72000.0000", "E"),  # longitude 720°
        ("9100.0000", "N", "01512.0000", "E"),  # latitude 91°
        ("5275.0000", "N", "01512.0000", "E"),  # 75 minutes
        ("5206.0000", "N", "01599.9990", "W"),  # 99.999 minutes
        ("9000.0001", "S", "01512.0000", "E"),  # just past the pole
    ],
)
def test_out_of_range_position_is_never_a_fix(lat, ns, lon, ew):
    rmc = nmea.sentence(f"GNRMC,120000.00,A,{lat},{ns},{lon},{ew},1.0,90.0,211125,,,A")
    gga = nmea.sentence(f"GNGGA,120000.00,{lat},{ns},{lon},{ew},4,14,0.7,100.0,M,40.0,M,,")
    for lines in ([rmc], [rmc, gga], [gga]):
        p, fixes = parse(lines)
        assert len(fixes) == 1 and not fixes[0].valid
        assert fixes[0].lat is None and fixes[0].lon is None
        assert p.stats.out_of_range == len(lines) and p.stats.no_fix == 1


def test_bad_position_in_one_sentence_spoils_the_epoch():
    good = nmea.rmc(1_763_700_000.0, 52.1, 15.2, 1.5, 90.0)
    bad_gga = nmea.sentence("GNGGA,044000.00,5206.0000,N,18100.0000,E,4,14,0.7,100.0,M,40.0,M,,")
    p, fixes = parse([good, bad_gga])
    assert len(fixes) == 1 and not fixes[0].valid and p.stats.out_of_range == 1


def test_out_of_range_time_drops_the_sentence():
    rmc = nmea.sentence("GNRMC,256000.00,A,5206.0000,N,01512.0000,E,1.0,90.0,211125,,,A")
    p, fixes = parse([rmc])
    assert fixes == [] and p.stats.out_of_range == 1 and p.stats.sentences["RMC"] == 0


def test_rmc_faa_mode_n_is_not_a_fix():
    rmc = nmea.sentence("GNRMC,120000.00,A,5206.0000,N,01512.0000,E,1.0,90.0,211125,,,N")
    p, fixes = parse([rmc])
    assert len(fixes) == 1 and not fixes[0].valid and fixes[0].rmc_status == "V"


# -- non-finite numbers -------------------------------------------------------


@pytest.mark.parametrize("bad", ["nan", "NaN", "inf", "-inf", "Infinity", "1e999"])
def test_non_finite_numbers_never_reach_a_fix(bad):
    gga = nmea.sentence(f"GNGGA,120000.00,5206.0000,N,01512.0000,E,4,14,{bad},{bad},M,40.0,M,,")
    rmc = nmea.sentence(f"GNRMC,120000.00,A,5206.0000,N,01512.0000,E,{bad},{bad},211125,,,A")
    vtg = nmea.sentence(f"GNVTG,{bad},T,,M,{bad},N,{bad},K,A")
    p, fixes = parse([rmc, gga, vtg], max_hdop=2.0)
    assert len(fixes) == 1
    f = fixes[0]
    assert_finite(f)
    assert f.hdop is None and f.altitude_m is None and f.speed_m_s is None and f.course_deg is None
    assert f.valid and f.fix_quality == 4  # the position is good; the bad numbers are missing
    assert p.stats.non_finite == 6  # GGA hdop + altitude, RMC speed + course, VTG km/h + course
    assert p.stats.malformed == 0


# -- the counters where the user looks: replay-nmea --json --------------------


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("humminbird-m37.nmea", {"fixes": 9, "no_fix": 0, "malformed": 0, "talkers": {"IN": 12}}),
        ("quectel-eg25-g-coldstart.nmea", {"fixes": 5, "no_fix": 3, "malformed": 0}),
        ("telit-pls83-w.nmea", {"fixes": 3, "no_fix": 0, "out_of_range": 0, "non_finite": 0}),
    ],
)
def test_replay_cli_reports_receiver_counters(tmp_path, name, expected):
    log = tmp_path / name
    log.write_text("\n".join(log_lines(name)) + "\n")
    out = subprocess.run(
        [sys.executable, "-m", "fieldrx_edge.cli", "replay-nmea", str(log), "--json"],
        capture_output=True,
        text=True,
        check=True,
    )
    res = json.loads(out.stdout.strip().splitlines()[-1])
    for key in ("out_of_range", "non_finite", "resync", "talkers", "bad_checksum"):
        assert key in res
    for key, v in expected.items():
        assert res[key] == v, key


# -- any field content: never a crash, never a non-finite or impossible fix ----

FIELD = st.one_of(
    st.sampled_from(["", "nan", "-inf", "1e999", "0", "-1", "90", "9000.0000", "18000.0000"]),
    st.sampled_from(["A", "V", "N", "S", "E", "W", "M", "K", "T", "RN", "AAN"]),
    st.from_regex(r"[0-9]{4,5}\.[0-9]{1,4}", fullmatch=True),
    st.floats(allow_nan=True, allow_infinity=True).map(str),
    st.text(alphabet="0123456789.-+eE", max_size=8),
)


TEMPLATES = {
    "GNRMC": ["A", "5206.0000", "N", "01512.0000", "E", "1.0", "90.0", "211125", "", "", "A"],
    "INGGA": [
        "5206.0000",
        "N",
        "01512.0000",
        "E",
        "4",
        "14",
        "0.7",
        "100.0",
        "M",
        "40.0",
        "M",
        "",
        "",
    ],
    "GNGNS": ["5206.0000", "N", "01512.0000", "E", "AA", "10", "0.8", "100.0", "40.0", "", "", "V"],
}
VTG = ["90.0", "T", "", "M", "1.0", "N", "1.9", "K", "A"]


@settings(max_examples=400, deadline=None)
@given(
    kinds=st.lists(st.sampled_from(sorted(TEMPLATES)), min_size=1, max_size=3, unique=True),
    times=st.lists(
        st.sampled_from(["", "120000.00", "120000.10", "235960.99", "250000"]),
        min_size=1,
        max_size=4,
    ),
    edits=st.lists(st.tuples(st.integers(0, 12), FIELD), max_size=4),
    vtg_edits=st.lists(st.tuples(st.integers(0, 8), FIELD), max_size=2),
)
def test_any_fields_give_only_finite_in_range_fixes(kinds, times, edits, vtg_edits):
    """Real sentence shapes with some fields replaced by anything a noisy line can carry."""
    p = NmeaParser(max_hdop=2.0)
    fixes: list[Fix] = []
    vtg = list(VTG)
    for i, v in vtg_edits:
        vtg[i] = v
    for t in times:
        for kind in kinds:
            fields = list(TEMPLATES[kind])
            for i, v in edits:
                if i < len(fields):
                    fields[i] = v
            fixes += p.feed(nmea.sentence(",".join([kind, t, *fields])))
        fixes += p.feed(nmea.sentence(",".join(["GNVTG", *vtg])))
    fixes += p.flush()
    for f in fixes:
        assert_finite(f)
        if f.valid:
            assert -90.0 <= f.lat <= 90.0 and -180.0 <= f.lon <= 180.0
        if f.hdop is not None:
            assert f.hdop >= 0.0


def test_replay_cli_text_shows_the_new_counters(tmp_path):
    log = tmp_path / "in.nmea"
    log.write_text("\n".join(log_lines("humminbird-m37.nmea")) + "\n")
    out = subprocess.run(
        [sys.executable, "-m", "fieldrx_edge.cli", "replay-nmea", str(log)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "lines 36, fixes 9 (no fix 0)" in out
    assert "out of range 0, non-finite 0, resync after binary 0, talkers {'IN': 12}" in out
