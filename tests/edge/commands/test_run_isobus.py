"""`fieldrx-edge run --implement isobus` against `fieldrx-edge ecu`, live, on one virtual
bus (both in this process: python-can's virtual bus does not cross processes)."""

from __future__ import annotations

import json
import threading

import pytest
from fieldrx_edge import cli
from fieldrx_edge.commands import run as run_cmd
from fieldrx_edge.sim.drive import write_nmea_log
from fieldrx_edge.sim.simulator import SimConfig

from tests.edge.isobus.test_network import channel
from tests.edge.jobfactory import trial_plot
from tests.support import scaled


def test_run_as_task_controller_drives_the_ecu_command(tmp_path, capsys):
    job = trial_plot()
    pkg = tmp_path / "job.json"
    pkg.write_bytes(job.to_json())
    log = tmp_path / "drive.nmea"
    write_nmea_log(job, log, SimConfig(seed=1), max_s=45.0)
    ch = channel()
    ecu_rc: list[int] = []
    ecu = threading.Thread(
        target=lambda: ecu_rc.append(
            cli.main(["ecu", "--can", f"virtual:{ch}", "--job", str(pkg), "--duration", "9"])
        )
    )
    ecu.start()
    rc = cli.main(
        [
            "run",
            str(pkg),
            "--state-dir",
            str(tmp_path / "state"),
            "--source",
            f"file:{log}",
            "--replay-speed",
            "8",
            "--offline",
            "--implement",
            "isobus",
            "--can",
            f"virtual:{ch}",
        ]
    )
    ecu.join(timeout=scaled(30))
    assert rc == 0 and ecu_rc == [0]
    outs = [json.loads(x) for x in capsys.readouterr().out.splitlines() if x.startswith("{")]
    run_out = next(o for o in outs if "records" in o)
    ecu_out = next(o for o in outs if "pool_bytes" in o)
    iso = run_out["isobus"]
    assert run_out["implement"] == "isobus" and run_out["records"] > 300
    assert iso["client"] is not None and iso["client"]["kind"] == "mass"
    assert iso["setpoints_sent"] > 10 and iso["values_rx"] > 10
    assert ecu_out["state"] == "connected" and ecu_out["setpoints_rx"] > 10
    assert ecu_out["tc_address"] == iso["address"]
    # the ECU worked the job through a JobSession: no uplink configured, nothing sent
    assert ecu_out["job_id"] == job.job_id and ecu_out["uplink_state"] == "offline"
    assert ecu_out["drained"] is True
    assert run_out["finished_cells"] >= 3
    # the implement's actual shaft speed and the applied rate reach the telemetry records
    from fieldrx_edge.protocol import TelemetryRecord
    from fieldrx_edge.uplink import TelemetryQueue

    q = TelemetryQueue(tmp_path / "state" / "queue.sqlite", job.machine_id)
    recs = [TelemetryRecord.from_dict(r) for r in q.pending(limit=5000)]
    q.close()
    metering = [r for r in recs if r.target_shaft_rpm and r.actual_shaft_rpm]
    assert len(metering) > 50
    good = [
        r
        for r in metering
        if abs(r.applied_rate_kg_ha - r.target_rate_kg_ha) < 0.05 * r.target_rate_kg_ha
    ]
    assert len(good) > 0.6 * len(metering)


def test_implement_isobus_needs_a_can_option(tmp_path):
    job = trial_plot()
    pkg = tmp_path / "job.json"
    pkg.write_bytes(job.to_json())
    with pytest.raises(SystemExit, match="--can"):
        cli.main(["run", str(pkg), "--state-dir", str(tmp_path), "--implement", "isobus"])


def test_simulate_behind_the_isobus_pair(capsys):
    rc = cli.main(
        ["simulate", "demo:35x23", "--implement", "isobus", "--json", "--compare-runs", "2"]
    )
    assert rc == 0
    out = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert out["implement"] == "isobus" and out["isobus"]["client"]["kind"] == "mass"
    assert out["mean_accuracy_pct"] >= 98.0


def test_bad_can_option_and_address_are_clear_errors(tmp_path, capsys):
    with pytest.raises(SystemExit, match="INTERFACE:CHANNEL"):
        cli.main(["ecu", "--can", "can0", "--duration", "0.1"])
    with pytest.raises(SystemExit, match="cannot open the CAN interface"):
        cli.main(["ecu", "--can", "nosuchiface:x", "--duration", "0.1"])
    with pytest.raises(SystemExit):
        cli.main(["ecu", "--can", "virtual:x", "--address", "0xFE"])
    assert "outside 0..253" in capsys.readouterr().err


def test_the_product_density_and_rate_unit_travel_in_the_job_package(tmp_path):
    """Before, a volume-rate implement could only be driven with --density typed in the
    cab; the package now carries the product's density and the prescription's unit."""
    import dataclasses

    from fieldrx_edge.job_package import JobPackage

    job = trial_plot()
    plain = job.to_json()
    assert b"rate_unit" not in plain  # defaults stay out: older packages keep their checksum
    uan = dataclasses.replace(job, product_density_kg_l=1.28, checksum="").seal()
    back = JobPackage.from_json(uan.to_json())
    units = run_cmd.job_rate_units(back)
    assert units.unit == "kg/ha" and units.density_kg_l == 1.28
    with pytest.raises(SystemExit, match="contradicts"):
        run_cmd.job_rate_units(back, 1.0)
    lha = dataclasses.replace(job, rate_unit="l/ha", checksum="").seal()
    assert run_cmd.job_rate_units(JobPackage.from_json(lha.to_json())).unit == "l/ha"
    # an old package: --density fills in
    assert run_cmd.job_rate_units(job, 1.1).density_kg_l == 1.1
    from fieldrx_edge.protocol import ProtocolError

    with pytest.raises(ProtocolError, match="rate_unit"):
        dataclasses.replace(job, rate_unit="gal/ac", checksum="").seal()
    with pytest.raises(ProtocolError, match="density"):
        dataclasses.replace(job, product_density_kg_l=40.0, checksum="").seal()
    # an l/ha job cannot go to the kg-per-revolution meter: refused, not metered wrongly
    pkg = tmp_path / "job.json"
    pkg.write_bytes(lha.to_json())
    with pytest.raises(SystemExit, match="l/ha"):
        cli.main(["run", str(pkg), "--state-dir", str(tmp_path), "--source", "file:/dev/null"])
