import json
import math
import socket
import subprocess
import sys
import threading
import time

import pyproj
import pytest
from fieldrx_edge.gnss import (
    NmeaParser,
    UtmProjection,
    file_lines,
    serial_lines,
    tcp_lines,
    udp_lines,
)
from fieldrx_edge.sim import nmea
from hypothesis import given, settings
from hypothesis import strategies as st

T0 = 1_763_700_000.0


def epoch(t, pos=(52.1, 15.2), v=1.5, c=90.0, talker="GN", q=4, hdop=0.7, valid=True):
    """One receiver epoch (RMC, GGA, VTG) at ``pos`` (lat, lon)."""
    lat, lon = pos
    return [
        nmea.rmc(t, lat, lon, v, c, valid=valid, talker=talker),
        nmea.gga(t, lat, lon, quality=q, hdop=hdop, talker=talker),
        nmea.vtg(v, c, talker=talker),
    ]


def feed_all(p, lines):
    out = []
    for ln in lines:
        out += p.feed(ln)
    return out + p.flush()


@settings(max_examples=40, deadline=None)
@given(
    lon=st.floats(min_value=-179.9, max_value=179.9),
    lat=st.floats(min_value=-79.9, max_value=83.9),
)
def test_utm_matches_pyproj_and_round_trips(lon, lat):
    zone = int((lon + 180) // 6) + 1
    epsg = (32600 if lat >= 0 else 32700) + zone
    p = UtmProjection(epsg)
    x, y = p.forward(lon, lat)
    px, py = pyproj.Transformer.from_crs(4326, epsg, always_xy=True).transform(lon, lat)
    assert abs(x - px) < 1e-4 and abs(y - py) < 1e-4
    lon2, lat2 = p.inverse(x, y)
    assert abs(lon2 - lon) < 1e-9 and abs(lat2 - lat) < 1e-9


def test_utm_rejects_non_utm_epsg():
    with pytest.raises(ValueError):
        UtmProjection(3857)


def test_epochs_merge_rmc_gga_vtg():
    p = NmeaParser()
    lines = epoch(T0) + epoch(T0 + 0.1, v=2.0) + epoch(T0 + 0.2, v=2.5)
    fixes = feed_all(p, lines)
    assert len(fixes) == 3
    f = fixes[1]
    assert f.types == {"RMC", "GGA", "VTG"} or f.types == {"RMC", "GGA"}
    assert f.fix_quality == 4 and f.hdop == 0.7 and f.n_sats == 14
    assert abs(f.speed_m_s - 2.0) < 1e-3 and f.course_deg == 90.0
    assert abs(f.t - (T0 + 0.1)) < 1e-6
    assert abs(f.lat - 52.1) < 1e-8 and abs(f.lon - 15.2) < 1e-8
    assert f.valid


def test_fix_is_emitted_without_waiting_for_next_epoch():
    p = NmeaParser()
    for ln in epoch(T0):
        p.feed(ln)
    rmc, gga, _ = epoch(T0 + 0.1)
    assert p.feed(rmc)[0].t == pytest.approx(T0)  # previous epoch closed by the new time
    got = p.feed(gga)
    assert len(got) == 1 and got[0].t == pytest.approx(T0 + 0.1)  # complete: emitted at once


def test_rmc_only_receiver_is_emitted_per_sentence():
    p = NmeaParser()
    got = [p.feed(nmea.rmc(T0 + i * 0.1, 52.1, 15.2, 1.5, 90.0, talker="GP")) for i in range(5)]
    # the first epoch waits until the type set is learned, then every RMC is a fix at once
    assert [len(g) for g in got] == [0, 2, 1, 1, 1]
    out = [f for g in got for f in g]
    assert all(f.fix_quality == 1 and f.valid for f in out)


def test_mixed_talkers_bad_checksums_truncation_garbage_counts():
    p = NmeaParser()
    lines = []
    lines += epoch(T0, talker="GP")
    lines += epoch(T0 + 0.1, talker="GN")
    lines += epoch(T0 + 0.2, talker="GL")
    good = nmea.rmc(T0 + 0.3, 52.1, 15.2, 1.5, 90.0)
    lines.append(good[:-2] + ("00" if good[-2:] != "00" else "11"))  # bad checksum
    lines.append(good[:25])  # truncated, no checksum
    lines.append("\x00\xff garbage ###")
    lines.append("")
    lines.append("$GPGSA,A,3,04,05,,09,12,,,24,,,,,2.5,1.3,2.1*39")  # other sentence
    lines += epoch(T0 + 0.4, talker="GN", q=0, valid=False)  # receiver lost the fix
    lines += epoch(T0 + 0.5, talker="GN", hdop=9.9)
    fixes = feed_all(p, lines)
    s = p.stats
    assert s.sentences == {"RMC": 5, "GGA": 5, "GNS": 0, "VTG": 5}
    assert s.bad_checksum == 1
    assert s.malformed == 3  # truncated, garbage, empty
    assert s.other_sentences == 1
    assert s.fixes == 5 and len(fixes) == 5
    assert s.no_fix == 1
    assert s.fix_quality == {4: 4, 0: 1}
    assert [f.talker for f in fixes] == ["GP", "GN", "GL", "GN", "GN"]


def test_hdop_limit_makes_fix_unusable():
    p = NmeaParser(max_hdop=5.0)
    fixes = feed_all(p, epoch(T0, hdop=9.9) + epoch(T0 + 0.1, hdop=1.0))
    assert [f.valid for f in fixes] == [False, True]


def test_lost_gga_does_not_shrink_the_epoch():
    p = NmeaParser()
    out = []
    for i in range(3):
        out += [x for ln in epoch(T0 + i * 0.1) for x in p.feed(ln)]
    e = epoch(T0 + 0.3)
    out += p.feed(e[0])  # GGA of this epoch lost
    e4 = epoch(T0 + 0.4)
    out += p.feed(e4[0])
    out += p.feed(e4[1])
    assert [round(f.t - T0, 1) for f in out] == [0.0, 0.1, 0.2, 0.3, 0.4]
    assert out[-1].types >= {"RMC", "GGA"}


def make_log(path):
    """A log with every kind of defect; returns the expected counts."""
    lines = []
    for i in range(200):
        t = T0 + i * 0.1
        talker = ("GP", "GN", "GL")[i % 3]
        lost = 100 <= i < 110
        e = epoch(
            t,
            v=1.5 + 0.1 * ((i * 7919) % 13 - 6) / 6,
            talker=talker,
            q=0 if lost else 4,
            valid=not lost,
        )
        if i % 17 == 5:
            e[0] = e[0][:-1] + ("0" if e[0][-1] != "0" else "1")  # RMC bad checksum
        if i % 23 == 7:
            e[2] = e[2][: len(e[2]) // 2]  # VTG truncated
        lines += e
        if i % 31 == 0:
            lines.append("$GPGSV,3,1,11,03,03,111,00,04,15,270,00,06,01,010,00,13,06,292,00*74")
        if i % 41 == 3:
            lines.append("#$%^ binary noise \x01\x02")
    path.write_text("\r\n".join(lines) + "\r\n")
    n_bad = len([i for i in range(200) if i % 17 == 5])
    n_trunc = len([i for i in range(200) if i % 23 == 7])
    n_noise = len([i for i in range(200) if i % 41 == 3])
    return {
        "RMC": 200 - n_bad,
        "GGA": 200,
        "VTG": 200 - n_trunc,
        "bad_checksum": n_bad,
        "malformed": n_trunc + n_noise,
        "no_fix": 10,
    }


def test_replay_cli_counts(tmp_path):
    log = tmp_path / "rx.nmea"
    exp = make_log(log)
    out = subprocess.run(
        [sys.executable, "-m", "fieldrx_edge.cli", "replay-nmea", str(log), "--json"],
        capture_output=True,
        text=True,
        check=True,
    )
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["sentences"] == {"RMC": exp["RMC"], "GGA": exp["GGA"], "GNS": 0, "VTG": exp["VTG"]}
    assert res["bad_checksum"] == exp["bad_checksum"]
    assert res["malformed"] == exp["malformed"]
    assert res["no_fix"] == exp["no_fix"]
    assert res["fixes"] == 200
    assert res["speed_filtered_std"] < 0.6 * res["speed_raw_std"]


def test_file_replay_pacing(tmp_path):
    log = tmp_path / "rx.nmea"
    lines = [ln for i in range(11) for ln in epoch(T0 + i * 0.1)]  # 1.0 s of log
    log.write_text("\n".join(lines))
    t = time.monotonic()
    assert len(list(file_lines(log, speed=4.0))) == 33
    dt = time.monotonic() - t
    assert 0.2 <= dt < 0.6  # 1 s of log at 4x
    t = time.monotonic()
    list(file_lines(log, speed=None))
    assert time.monotonic() - t < 0.1


def test_tcp_source_reads_lines():
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)
    port = srv.getsockname()[1]
    lines = epoch(T0) + epoch(T0 + 0.1)

    def serve():
        c, _ = srv.accept()
        c.sendall(("\r\n".join(lines) + "\r\n").encode())
        time.sleep(0.2)
        c.close()

    threading.Thread(target=serve, daemon=True).start()
    it = tcp_lines("127.0.0.1", port)
    got = [next(it) for _ in range(len(lines))]
    assert got == lines
    srv.close()


def test_udp_source_reads_datagrams():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    it = udp_lines("127.0.0.1", port, timeout_s=0.2)
    lines = epoch(T0)

    def send():
        time.sleep(0.1)
        u = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        u.sendto("\r\n".join(lines).encode(), ("127.0.0.1", port))
        u.close()

    threading.Thread(target=send, daemon=True).start()
    got = []
    while len(got) < 3:
        ln = next(it)
        if ln:
            got.append(ln)
    assert got == lines


def test_meridian_convergence_matches_pyproj():
    p = UtmProjection(32633)
    for lon, lat in ((17.9, 52.0), (12.1, 48.0), (15.0, 60.0)):
        ref = pyproj.Proj("EPSG:32633").get_factors(lon, lat).meridian_convergence
        assert abs(math.degrees(p.convergence_rad(lon, lat)) - ref) < 1e-4


def test_serial_source_reads_a_pty():
    import os

    master, slave = os.openpty()
    try:
        it = serial_lines(os.ttyname(slave), 115200, timeout_s=0.2)
        assert next(it) == ""  # port open, receiver silent: a timeout, not a hang
        lines = epoch(T0)
        os.write(master, ("\r\n".join(lines) + "\r\n").encode())
        got = []
        for _ in range(50):
            ln = next(it)
            if ln:
                got.append(ln)
            if len(got) == 3:
                break
        assert got == lines
    finally:
        os.close(master)
        os.close(slave)
