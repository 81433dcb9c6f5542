import json
import subprocess
import sys

import httpx
import pytest
from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.jobs import JobStore, pull
from fieldrx_edge.metering import rate_for_shaft_rpm
from fieldrx_edge.ndvi import SEED000_TABLE, NdviMode, NdviRateMap, NdviSample, parse_line
from fieldrx_edge.protocol import ProtocolError

from .jobfactory import trial_plot
from .peer import Peer


def test_pull_verifies_caches_and_uses_etag(tmp_path):
    peer = Peer().start()
    try:
        a = trial_plot(job_id=11)
        b = trial_plot(job_id=12, seed=5)
        peer.packages = {11: a.to_json(), 12: b.to_json()}
        store = JobStore(tmp_path)
        out = pull(store, peer.url, "dev-token")
        assert out == {"downloaded": [11, 12], "unchanged": [], "failed": {}}
        assert store.load(11).checksum == a.checksum
        assert (11, "downloaded") in peer.states
        assert store.config()["token"] == "dev-token"
        assert (tmp_path / "config.json").stat().st_mode & 0o777 == 0o600
        out = pull(store, peer.url, "dev-token")
        assert out["unchanged"] == [11, 12]
        # a tampered package is refused and the good cached copy kept
        body = json.loads(a.to_json())
        body["rate_kg_ha"][0] += 1
        peer.packages[11] = json.dumps(body).encode()
        out = pull(store, peer.url, "dev-token")
        assert 11 in out["failed"] and "checksum" in out["failed"][11]
        assert store.load(11).rate_kg_ha[0] == a.rate_kg_ha[0]
        with pytest.raises(httpx.HTTPStatusError):
            pull(store, peer.url, "wrong-token")
    finally:
        peer.stop()


def test_pull_cli_then_offline_run(tmp_path):
    peer = Peer().start()
    try:
        peer.packages = {21: trial_plot(job_id=21).to_json()}
        r = subprocess.run(
            [
                sys.executable,
                "-m",
                "fieldrx_edge.cli",
                "pull",
                "--server",
                peer.url,
                "--token",
                "dev-token",
                "--state-dir",
                str(tmp_path),
            ],
            capture_output=True,
            text=True,
            check=True,
        )
        assert json.loads(r.stdout)["downloaded"] == [21]
    finally:
        peer.stop()
    assert JobStore(tmp_path).job_ids() == [21]
    pkg = JobStore(tmp_path).load(21)
    assert isinstance(pkg, JobPackage)


def test_store_rejects_bad_package(tmp_path):
    with pytest.raises(ProtocolError):
        JobStore(tmp_path).save_package(b'{"format_version": 1}')


def test_ndvi_rate_map_end_points_and_clamp():
    m = NdviRateMap()
    assert m.rate(0.24) == pytest.approx(375.0)
    assert m.rate(0.65) == pytest.approx(180.0)
    assert m.rate(0.10) == 375.0 and m.rate(0.90) == 180.0
    assert m.rate(0.445) == pytest.approx(277.5)


def test_ndvi_mode_averages_four_sensors_and_window_15():
    mode = NdviMode()
    ds = []
    for i in range(30):
        v = 0.4 if i < 15 else 0.6
        ds.append(
            mode.on_sample(NdviSample(None, (v - 0.02, v + 0.02, v - 0.01, v + 0.01)), 6 / 3.6)
        )
    assert ds[14].ndvi == pytest.approx(0.4)
    assert ds[22].ndvi == pytest.approx((7 * 0.4 + 8 * 0.6) / 15)
    assert ds[29].ndvi == pytest.approx(0.6)
    d = ds[29]
    # the shaft speed meters the mapped rate through the table calibration
    assert rate_for_shaft_rpm(SEED000_TABLE, d.target_rpm, 3.6, 6 / 3.6) == pytest.approx(
        d.rate_kg_ha
    )
    assert SEED000_TABLE.min_rpm <= d.target_rpm <= SEED000_TABLE.max_rpm


def test_ndvi_parse_and_cli(tmp_path):
    assert parse_line("1.0,0.5,0.5,0.5,0.5").t == 1.0
    assert parse_line("0.5,0.5,0.5,0.5").t is None
    assert parse_line("0.5,0.5") is None and parse_line("x,y,z,w") is None
    assert parse_line("0.5,0.5,7,0.5") is None  # NDVI outside [-1, 1]
    f = tmp_path / "ndvi.csv"
    f.write_text(
        "# t,s1,s2,s3,s4\n"
        + "\n".join(f"{i * 0.1},0.3,0.31,0.29,0.3" for i in range(20))
        + "\nbad\n"
    )
    r = subprocess.run(
        [sys.executable, "-m", "fieldrx_edge.cli", "ndvi", f"file:{f}", "--json"],
        capture_output=True,
        text=True,
        check=True,
    )
    out = json.loads(r.stdout)
    assert out["samples"] == 20 and out["bad_lines"] == 1
    assert out["mean_rate_kg_ha"] == pytest.approx(NdviRateMap().rate(0.3))


def test_ndvi_mode_queues_records_with_gnss_speed(tmp_path):
    import sqlite3
    import time as _time

    from fieldrx_edge.sim.drive import write_nmea_log
    from fieldrx_edge.sim.simulator import SimConfig

    gnss = tmp_path / "rx.nmea"
    write_nmea_log(trial_plot(), gnss, SimConfig(seed=1), max_s=30.0)
    f = tmp_path / "ndvi.csv"
    f.write_text("\n".join(f"{i * 0.1},0.5,0.52,0.48,0.5" for i in range(40)))
    _time.sleep(0.01)
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "fieldrx_edge.cli",
            "ndvi",
            f"file:{f}",
            "--gnss",
            f"file:{gnss}",
            "--replay-speed",
            "0",
            "--machine-id",
            "4",
            "--state-dir",
            str(tmp_path / "st"),
            "--offline",
            "--json",
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["samples"] == 40 and out["queue"]["last_seq"] == 40
    con = sqlite3.connect(tmp_path / "st" / "queue.sqlite")
    bodies = [json.loads(b) for (b,) in con.execute("SELECT body FROM records ORDER BY seq")]
    assert all(b["ndvi"] == pytest.approx(0.5) and b["machine_id"] == 4 for b in bodies)
    assert all(b["target_rate_kg_ha"] == pytest.approx(NdviRateMap().rate(0.5)) for b in bodies)
