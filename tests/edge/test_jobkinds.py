"""On the tractor: kind settings (papers' defaults, unit-checked), sensor line
formats, the hold-then-stop guard on bad sensor input, the package's kind fields, the
optional telemetry fields, and `fieldrx-edge run` of a cached sensor job from files."""

from __future__ import annotations

import dataclasses
import json
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.jobkinds.sensors import (
    SensorError,
    SensorGuard,
    depth_line,
    ndvi_line,
    parse_depth_mv,
    parse_ndvi,
)
from fieldrx_edge.jobkinds.settings import SettingsError, validate_settings
from fieldrx_edge.jobkinds.topdress import TopdressLoop
from fieldrx_edge.ndvi import SEED000_TABLE
from fieldrx_edge.protocol import ProtocolError, TelemetryRecord
from fieldrx_edge.sim.fields import RectField, rect_job

from tests.support import scaled

BIN = Path(sys.executable).parent
ROOT = Path(__file__).resolve().parents[2]


def kind_job(kind: str, **settings: object) -> JobPackage:
    job = rect_job(RectField(length_m=40, width_m=3.6 * 4, implement_width_m=3.6))
    return dataclasses.replace(
        job,
        kind=kind,
        kind_settings=validate_settings(kind, settings),
        calibration=SEED000_TABLE.to_dict(),
        checksum="",
    ).seal()


def test_defaults_are_the_papers() -> None:
    s = validate_settings("ndvi_topdress", {})
    assert s["rate_curve"] == {
        "ndvi_lo": 0.24, "rate_at_lo_kg_ha": 375.0, "ndvi_hi": 0.65, "rate_at_hi_kg_ha": 180.0
    }  # fmt: skip
    assert s["sensors"]["count"] == 4 and s["sensors"]["layout"] == "distributed"
    assert s["sensors"]["height_m"] == 0.88 and s["window"] == 15
    assert s["controller"]["params"] == {
        "kp": 0.15, "ki": 0.32, "kd": 0.07, "eps": 0.7, "rule": "relative_change"
    }  # fmt: skip
    assert s["implement_width_m"] == 3.6
    d = validate_settings("seeding_depth", {})
    assert d["target_depth_mm"] == 30.0 and d["controller"]["name"] == "fuzzy_pid"
    assert d["sensor_calibration"] == {
        "slope_mm_per_mv": -0.065, "intercept_mm": 270.35,
        "signal_min_mv": 2628.0, "signal_max_mv": 4356.0,
    }  # fmt: skip
    assert d["actuator_speed_mm_s"] == 50.0
    # choosing LADRC brings its own parameters and period, not the ISP's gains
    lad = validate_settings("ndvi_topdress", {"controller": {"name": "ladrc"}})["controller"]
    assert lad["params"]["order"] == 1 and lad["period_s"] == 0.02


@pytest.mark.parametrize(
    ("kind", "given", "where"),
    [
        ("ndvi_topdress", {"rate_curve": {"ndvi_hi": 0.2}}, "settings.rate_curve.ndvi_hi"),
        ("ndvi_topdress", {"rate_curve": {"ndvi_lo": 1.5}}, "settings.rate_curve.ndvi_lo"),
        ("ndvi_topdress", {"window": 0}, "settings.window"),
        ("ndvi_topdress", {"window": 2.5}, "settings.window"),
        ("ndvi_topdress", {"sensors": {"sample_hz": 50}}, "settings.sensors.sample_hz"),
        ("ndvi_topdress", {"controller": {"name": "fuzzy_pid"}}, "settings.controller.name"),
        ("ndvi_topdress", {"rate": 3}, "settings.rate"),
        ("seeding_depth", {"target_depth_mm": "30"}, "settings.target_depth_mm"),
        ("seeding_depth", {"target_depth_mm": 500}, "settings.target_depth_mm"),
        (
            "seeding_depth",
            {"sensor_calibration": {"signal_max_mv": 1000}},
            "settings.sensor_calibration.signal_max_mv",
        ),
        ("seeding_depth", {"speed_bands_kmh": [[3, 1]]}, "settings.speed_bands_kmh.0"),
        ("prescription_map", {"window": 3}, "settings."),
    ],
)
def test_bad_settings_name_the_field(kind: str, given: dict, where: str) -> None:
    with pytest.raises(SettingsError) as exc:
        validate_settings(kind, given)
    assert exc.value.where == where


def test_sensor_lines() -> None:
    line = ndvi_line(1.5, [0.41, 0.42, 0.43, 0.44])
    assert parse_ndvi(line, 4) == (1.5, [0.41, 0.42, 0.43, 0.44])
    assert parse_ndvi("0.4,0.5,0.6,0.7", 4) == (None, [0.4, 0.5, 0.6, 0.7])
    cases = [
        (line[:-2] + "00", "checksum"),
        (ndvi_line(1.0, [0.4, 1.2, 0.4, 0.4]), "range"),
        (ndvi_line(1.0, [0.4, 0.4, 0.4]), "format"),
        ("0.4,abc,0.4,0.4", "format"),
        ("0.4,nan,0.4,0.4", "range"),
        ("$NDVI,1,0.4,0.4,0.4,0.4", "format"),
    ]
    for bad, reason in cases:
        with pytest.raises(SensorError) as exc:
            parse_ndvi(bad, 4)
        assert exc.value.reason == reason, bad
    assert parse_depth_mv(depth_line(2.0, 3700.0), 2628, 4356) == (2.0, 3700.0)
    for bad, reason in [(depth_line(2.0, 5000.0), "range"), ("12,x", "format")]:
        with pytest.raises(SensorError) as exc:
            parse_depth_mv(bad, 2628, 4356)
        assert exc.value.reason == reason


def test_guard_holds_then_stops() -> None:
    g = SensorGuard(hold_s=1.0)
    assert g.value(0.0) == (None, ["sensor_lost"])  # nothing good yet: no output
    g.good(0.0, 0.5)
    assert g.value(0.0) == (0.5, [])
    assert g.value(0.9) == (0.5, ["sensor_fault"])  # held, alarmed
    assert g.value(1.2) == (None, ["sensor_lost"])  # beyond the hold: stop
    g.good(1.3, 0.6)
    assert g.value(1.3) == (0.6, [])


def test_topdress_loop_stops_outside_and_when_lost() -> None:
    job = kind_job("ndvi_topdress")
    loop = TopdressLoop(job)
    d = loop.on_sample(0.0, [0.24] * 4, 1.5)
    assert d.rate_kg_ha == pytest.approx(375.0) and d.target_rpm > 0 and not d.alarms
    d = loop.on_sample(0.1, [0.24] * 4, 1.5, inside=False)
    assert d.target_rpm == 0.0 and "outside_field" in d.alarms
    d = loop.on_sample(0.5, None, 1.5)  # bad line: last good NDVI, alarmed
    assert d.target_rpm > 0 and d.alarms == ["sensor_fault"]
    d = loop.on_sample(1.2, None, 1.5)  # beyond the 1 s hold
    assert d.target_rpm == 0.0 and d.alarms == ["sensor_lost"]


def test_package_kind_fields() -> None:
    plain = rect_job()
    body = json.loads(plain.to_json())
    assert "kind" not in body and "kind_settings" not in body  # old bytes, old checksum
    job = kind_job("seeding_depth")
    back = JobPackage.from_json(job.to_json())
    assert back.kind == "seeding_depth" and back.kind_settings["target_depth_mm"] == 30.0
    tampered = json.loads(job.to_json())
    tampered["kind_settings"]["target_depth_mm"] = 50.0
    with pytest.raises(ProtocolError, match="checksum"):
        JobPackage.from_json(json.dumps(tampered))
    tampered["kind"] = "mowing"
    with pytest.raises(ProtocolError, match="kind"):
        JobPackage.from_json(json.dumps(tampered), verify=False)


def test_optional_telemetry_fields() -> None:
    rec = TelemetryRecord(machine_id=1, seq=1, t=1.7e9)
    assert "ndvi_raw" not in rec.to_dict()  # prescription-map records keep their shape
    d = TelemetryRecord(machine_id=1, seq=1, t=1.7e9, ndvi_raw=0.4, gain_kp=12.0).to_dict()
    assert d["ndvi_raw"] == 0.4 and d["gain_kp"] == 12.0
    assert TelemetryRecord.from_dict(d).gain_kp == 12.0
    with pytest.raises(ProtocolError, match="actuator_mm"):
        TelemetryRecord.from_dict({**d, "actuator_mm": float("nan")})


def _queued(state: Path) -> list[dict]:
    """The agent's queued records; none yet while the queue file exists but its schema is
    not committed (a poll can open the file between the agent creating it and creating the
    table: "no such table: records" failed this under load)."""
    con = sqlite3.connect(next(state.rglob("*.sqlite")))
    try:
        rows = con.execute("SELECT body FROM records ORDER BY seq").fetchall()
    except sqlite3.OperationalError as exc:
        if "no such table" not in str(exc):
            raise
        return []
    finally:
        con.close()
    return [json.loads(r[0]) for r in rows]


def test_run_ndvi_job_from_files_holds_then_stops(tmp_path: Path) -> None:
    from fieldrx_edge.sim.drive import write_nmea_log

    # the replayed GNSS ends wherever the log ends: the boundary rule is tested above
    job = kind_job("ndvi_topdress", restrict_to_boundary=False)
    pkg = tmp_path / "job.json"
    pkg.write_bytes(job.to_json())
    write_nmea_log(job, tmp_path / "gnss.nmea", max_s=20.0)
    lines = [ndvi_line(0.1 * i, [0.3, 0.31, 0.32, 0.33]) for i in range(1, 21)]
    lines += ["$NDVI,2.1,0.3,0.3,0.3,0.3*00", "garbage", "0.3,0.3,1.7,0.3"]  # held
    lines += ["0.3,0.3,0.3"] * 10  # 1 s more of bad lines: beyond the hold -> stop
    lines += [ndvi_line(4.0, [0.6, 0.6, 0.6, 0.6])]
    (tmp_path / "ndvi.log").write_text("\n".join(lines) + "\n")
    out = subprocess.run(
        [str(BIN / "fieldrx-edge"), "run", str(pkg), "--source", f"file:{tmp_path / 'gnss.nmea'}",
         "--sensor", f"file:{tmp_path / 'ndvi.log'}", "--offline",
         "--state-dir", str(tmp_path / "state")],
        cwd=ROOT, capture_output=True, text=True, timeout=scaled(120),
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["records"] == len(lines)
    assert res["sensor_errors"] == {"checksum": 1, "format": 11, "range": 1}
    recs = _queued(tmp_path / "state")
    assert len(recs) == len(lines)
    assert recs[0]["ndvi_raw"] == pytest.approx(0.315)
    # (shaft speeds depend on the replayed GNSS speed, which races the sensor file: rates do not)
    assert recs[21]["alarms"] == ["sensor_fault"] and recs[21]["target_rate_kg_ha"] > 300.0
    assert "sensor_lost" in recs[-2]["alarms"] and recs[-2]["target_rate_kg_ha"] == 0.0
    assert recs[-2]["target_shaft_rpm"] == 0.0
    assert recs[-1]["alarms"] == [] and recs[-1]["target_rate_kg_ha"] < 300.0
    # the shaft loop (seed 000's chain, --motor sim) follows the target while it is metering
    spinning = [r for r in recs[:20] if r["target_shaft_rpm"] > 0]
    assert all(r["actual_shaft_rpm"] >= 0 and "duty" in r for r in recs)
    if spinning:  # (the replayed GNSS speed races the sensor file, see above)
        assert spinning[-1]["actual_shaft_rpm"] > 0


def test_run_depth_job_from_files(tmp_path: Path) -> None:
    from fieldrx_edge.jobkinds.seeding import DepthJobLoop
    from fieldrx_edge.sim.drive import write_nmea_log

    job = kind_job("seeding_depth")
    pkg = tmp_path / "job.json"
    pkg.write_bytes(job.to_json())
    write_nmea_log(job, tmp_path / "gnss.nmea", max_s=10.0)
    cal = DepthJobLoop(job).cal
    lines = [depth_line(0.1 * i, cal.signal_mv(33.0)) for i in range(1, 11)]  # 3 mm deep
    lines += [depth_line(1.1, 5000.0), depth_line(1.2, 1000.0)]  # out of range: held
    lines += ["$DEPTH,1.3,3700*00"] + ["x"] * 6  # checksum, format: beyond 0.5 s -> lost
    lines += [depth_line(2.5, cal.signal_mv(30.0))]
    (tmp_path / "depth.log").write_text("\n".join(lines) + "\n")
    out = subprocess.run(
        [str(BIN / "fieldrx-edge"), "run", str(pkg), "--source", f"file:{tmp_path / 'gnss.nmea'}",
         "--sensor", f"file:{tmp_path / 'depth.log'}", "--offline",
         "--state-dir", str(tmp_path / "state")],
        cwd=ROOT, capture_output=True, text=True, timeout=scaled(120),
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["sensor_errors"] == {"range": 2, "checksum": 1, "format": 6}
    recs = _queued(tmp_path / "state")
    assert recs[0]["depth_mm"] == pytest.approx(33.0, abs=0.01)
    assert recs[9]["duty"] < 0  # too deep: the loop drives the roller to shallower
    assert recs[10]["alarms"] == ["sensor_fault"] and recs[10]["depth_mm"] == recs[9]["depth_mm"]
    lost = [r for r in recs if "sensor_lost" in r["alarms"]]
    assert lost and all(r["depth_mm"] is None and r["duty"] == 0.0 for r in lost)
    # command 0: the cylinder coasts to a stop (seed 002's 0.592 s mechanism), never pushed
    pos = [r["actuator_mm"] for r in lost]
    steps = [abs(b - a) for a, b in zip(pos, pos[1:], strict=False)]
    assert all(b < a for a, b in zip(steps, steps[1:], strict=False))
    assert recs[-1]["alarms"] == [] and recs[-1]["depth_mm"] == pytest.approx(30.0, abs=0.01)


def test_simulation_paced_for_the_live_view() -> None:
    import time

    from fieldrx_edge.jobkinds.topdress import simulate_topdress

    got: list[dict] = []
    t0 = time.time()
    out = simulate_topdress(kind_job("ndvi_topdress"), seed=1, sink=got.extend, realtime=400.0)
    wall = time.time() - t0
    assert len(got) == out["records"]
    assert wall >= 0.9 * out["duration_s"] / 400.0  # paced, not as fast as possible
    ts = np.array([r["t"] for r in got])
    # a record's time is its fix time: fixes stay 1 / hz apart in record time,
    # paced or not (wall-clock stamps were 1 / 400 of that), and none is stamped in the future
    assert np.all(np.diff(ts) > 0)
    assert np.allclose(np.diff(ts), 0.1, atol=2e-3)
    assert all(r["fix_period_s"] == 0.1 for r in got)
    assert ts[-1] <= time.time() + 0.01


def test_run_notices_a_silent_sensor(tmp_path: Path) -> None:
    """A live sensor (TCP here, like a serial link) sends 8 good lines and then nothing:
    the loop holds the last value for the job's hold time, then stops and alarms, on its own."""
    import signal
    import socket
    import threading
    import time

    from fieldrx_edge.sim.drive import write_nmea_log

    job = kind_job("ndvi_topdress", restrict_to_boundary=False, sensor_hold_s=0.5)
    pkg = tmp_path / "job.json"
    pkg.write_bytes(job.to_json())
    write_nmea_log(job, tmp_path / "gnss.nmea", max_s=5.0)
    srv = socket.create_server(("127.0.0.1", 0))
    port = srv.getsockname()[1]
    done = threading.Event()

    def serve() -> None:
        conn, _ = srv.accept()
        for i in range(8):
            conn.sendall((ndvi_line(0.1 * i, [0.4, 0.41, 0.42, 0.43]) + "\n").encode())
            time.sleep(0.1)
        done.wait(10)  # then silent, connection open: a dead sensor on a live link
        conn.close()

    threading.Thread(target=serve, daemon=True).start()
    p = subprocess.Popen(
        [str(BIN / "fieldrx-edge"), "run", str(pkg), "--source", f"file:{tmp_path / 'gnss.nmea'}",
         "--sensor", f"tcp:127.0.0.1:{port}", "--offline", "--state-dir", str(tmp_path / "state")],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + scaled(
            8
        )  # silence noticed on the wall clock, not per read timeout
        recs: list[dict] = []
        while time.monotonic() < deadline:
            time.sleep(0.5)
            if (tmp_path / "state" / "queue.sqlite").exists():
                recs = _queued(tmp_path / "state")
                if any("sensor_lost" in r["alarms"] for r in recs):
                    break
    finally:
        done.set()
        p.send_signal(signal.SIGTERM)
        p.wait(10)
        srv.close()
    good = [r for r in recs if not r["alarms"]]
    held = [r for r in recs if r["alarms"] == ["sensor_fault"]]
    lost = [r for r in recs if "sensor_lost" in r["alarms"]]
    assert len(good) == 8 and held and lost, [r["alarms"] for r in recs]
    assert all(r["ndvi"] is not None and r["target_rate_kg_ha"] > 0 for r in held)
    assert all(r["target_shaft_rpm"] == 0.0 and r["target_rate_kg_ha"] == 0.0 for r in lost)
    assert recs.index(held[0]) < recs.index(lost[0])


def test_depth_job_controllers_are_the_papers_with_shared_base_gains() -> None:
    from fieldrx_edge.control import PID, FuzzyPID
    from fieldrx_edge.depth import DEPTH_PID_GAINS
    from fieldrx_edge.jobkinds.seeding import build_depth_controller

    s = validate_settings("seeding_depth", {})
    fz = build_depth_controller(s["controller"], s["actuator_speed_mm_s"])
    assert isinstance(fz, FuzzyPID)
    # seed 002 Table 2: 6/200, 6/50, 0.9/3, 0.06/3, 1.5/3 (once tuned factors on the unit step)
    assert (fz.k_e, fz.k_ec, fz.k_dkp, fz.k_dki, fz.k_dkd) == (0.03, 0.12, 0.30, 0.02, 0.5)
    pid = build_depth_controller(
        validate_settings("seeding_depth", {"controller": {"name": "pid"}})["controller"], 50.0
    )
    assert isinstance(pid, PID)
    for c in (fz, pid):  # the same K' and derivative filter for both, limited at 50 mm/s
        assert (c.kp, c.ki, c.kd) == tuple(DEPTH_PID_GAINS.values())
        assert c.n == fz.n and c.out_max == pytest.approx(50.0 / 2.6091)


def test_depth_simulation_dug_out_telemetry_and_cylinder() -> None:
    from fieldrx_edge.jobkinds.seeding import DepthDisturbance, simulate_seeding

    pid = validate_settings("seeding_depth", {"controller": {"name": "pid"}})["controller"]
    job = kind_job("seeding_depth")
    base = simulate_seeding(job, seed=2, controller=pid)
    fuzzy = simulate_seeding(job, seed=2)
    quiet = simulate_seeding(
        job, seed=2, controller=pid, disturbance=DepthDisturbance(sensor_noise_mv=0.0)
    )
    fast = simulate_seeding(
        kind_job("seeding_depth", actuator_speed_mm_s=500.0), seed=2, controller=pid
    )

    def sd(out: dict, table: str) -> list[float]:
        return [b["sd_mm"] for b in out[table]["bands"]]

    # the same soil under both controllers
    assert fuzzy["open_loop_table"] == base["open_loop_table"]
    assert fuzzy["gains"]["kd"][0] < 3.0 and base["gains"]["kd"] == [3.0, 0.0]
    # the sensor's reading adds its noise to the true (dug-out) depth, in every band
    reading, dug = sd(base, "depth_table"), sd(base, "true_depth_table")
    assert all(m > t for m, t in zip(reading, dug, strict=True))
    assert sd(quiet, "depth_table") == pytest.approx(sd(quiet, "true_depth_table"), abs=1e-9)
    # control removes most of the soil's variation, and the cylinder speed of the settings
    # is the plant's (it was 50 mm/s whatever the settings said)
    for o, t, f in zip(sd(base, "open_loop_table"), dug, sd(fast, "true_depth_table"), strict=True):
        assert t < 0.6 * o and f < 0.9 * t
