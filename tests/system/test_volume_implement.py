"""End to end: a liquid's prescription from the server reaches a volume-rate ISOBUS
implement through the edge agent (``fieldrx-edge run --implement isobus``) with no option
typed in the cab: one prescribed in l/ha, one in kg/ha whose product has a density.

The implement is the recorded AgIsoStack++ sprayer client (``tests/edge``: its frames from
the trace, its 16-section pool with setpoint volume per area, DDI 1, on the bin element 3),
run in real time next to the agent on one python-can virtual bus.
"""

from __future__ import annotations

import json
import threading
from dataclasses import dataclass

import can
import pytest
from fieldrx_edge import cli
from fieldrx_edge.isobus import process_data as pdm
from fieldrx_edge.isobus.j1939 import PGN_PROCESS_DATA, Name, decode_id
from fieldrx_edge.isobus.network import Node
from fieldrx_edge.sim.drive import write_nmea_log
from fieldrx_edge.sim.simulator import SimConfig

from tests.edge import peer_sprayer
from tests.edge.isobus.test_network import channel
from tests.edge.isobus.test_tc_server_peer_replay import PeerClient, Recorded, load_trace
from tests.support import SEED001_CAL
from tests.support.plans import API
from tests.support.prescriptions import make_rx, setup_plan


@dataclass
class QuickStart(Recorded):
    """The recorded client without its 7.6 s start-up pause (the drive is short)."""

    @property
    def startup_delay_s(self) -> float:
        return 0.5


class SeesTheTcFirst(PeerClient):
    """Starts its handshake once the TC's status broadcast is seen (as AgIsoStack++'s
    client does): the agent's TC comes up after the sprayer here."""

    def update(self) -> None:
        if self.state == "startup" and not any(
            m.pgn == PGN_PROCESS_DATA and m.data[:1] == b"\xfe" for m in self.got
        ):
            self.t_claim = self.node.clock()
            return
        super().update()


def run_peer(ch: str, stop: threading.Event) -> PeerClient:
    rec = QuickStart(load_trace())
    claim = rec.claim
    bus = can.Bus(interface="virtual", channel=ch, receive_own_messages=False)
    node = Node(bus, Name.from_bytes(claim.data), decode_id(claim.can_id)[1], label="sprayer")
    peer = SeesTheTcFirst(node, rec, peer_sprayer.pool())

    def loop() -> None:
        peer.start()
        while not stop.is_set():
            node.poll(0.002)
            node.update()
            peer.update()
        node.close()

    threading.Thread(target=loop, daemon=True).start()
    return peer


def drive(tmp_path, pkg_bytes: bytes, capsys) -> tuple[dict, list[int]]:
    """The agent runs the package against the sprayer: its summary and the DDI 1 setpoints
    (element 3) the sprayer received."""
    from fieldrx_edge.job_package import JobPackage

    job = JobPackage.from_json(pkg_bytes)
    pkg = tmp_path / "job.json"
    pkg.write_bytes(pkg_bytes)
    log = tmp_path / "drive.nmea"
    write_nmea_log(job, log, SimConfig(seed=1), max_s=60.0)
    ch, stop = channel(), threading.Event()
    peer = run_peer(ch, stop)
    try:
        rc = cli.main(
            [
                "run",
                str(pkg),
                "--state-dir",
                str(tmp_path / "state"),
                "--source",
                f"file:{log}",
                "--replay-speed",
                "6",
                "--offline",
                "--implement",
                "isobus",
                "--can",
                f"virtual:{ch}",
            ]
        )
    finally:
        stop.set()
    assert rc == 0
    outs = [json.loads(x) for x in capsys.readouterr().out.splitlines() if x.startswith("{")]
    run_out = next(o for o in outs if "records" in o)
    assert peer.state == "active", peer.state
    sets = [
        pdm.decode(m.data)
        for m in list(peer.got)
        if m.pgn == PGN_PROCESS_DATA and len(m.data) == 8 and m.data[0] & 0x0F == pdm.CMD_VALUE
    ]
    return run_out, [p.value for p in sets if p.element == 3 and p.ddi == 1]


@pytest.fixture()
def uan(client, org):
    h = org.headers()
    plan = setup_plan(client, h)
    m = client.post(
        f"{API}/machines",
        headers=h,
        json={"name": "Sprayer", "width_m": 2.3, "lag_s": 1.0, "calibration": SEED001_CAL},
    ).json()
    body = {"model": "uniform", "params": {"rate_kg_ha": 192}, "product_key": "default:uan28"}
    return h, plan, m, body


@pytest.mark.parametrize("unit", ["l/ha", "kg/ha"])
def test_a_liquid_prescription_drives_a_volume_implement_with_no_cab_option(
    unit, uan, client, db, tmp_path, capsys
) -> None:
    from fieldrx.db.models import Machine
    from fieldrx.services.jobpackage import build_package

    h, plan, m, body = uan
    rx = make_rx(client, h, plan["id"], rate_unit=unit, **body)
    pkg = build_package(db, rx["id"], None, db.get(Machine, m["id"]))
    assert pkg.rate_unit == unit and pkg.product_density_kg_l == 1.28
    run_out, ddi1 = drive(tmp_path, pkg.to_json(), capsys)
    iso = run_out["isobus"]
    assert iso["client"] is not None and iso["client"]["kind"] == "volume", iso
    # 192 kg/ha of UAN-28 at 1.28 kg/l = 150 l/ha = 1 500 000 x 0.01 mm^3/m^2 (DDI 1)
    assert ddi1 and set(ddi1) <= {0, 1_500_000} and 1_500_000 in ddi1, ddi1
    assert "isobus_cannot_drive" not in json.dumps(run_out)
    # the telemetry stays in kg/ha whatever the job's unit (the server's as-applied maps)
    from fieldrx_edge.protocol import TelemetryRecord
    from fieldrx_edge.uplink import TelemetryQueue

    q = TelemetryQueue(tmp_path / "state" / "queue.sqlite", pkg.machine_id)
    recs = [TelemetryRecord.from_dict(r) for r in q.pending(limit=5000)]
    q.close()
    targets = {round(r.target_rate_kg_ha, 6) for r in recs if r.target_rate_kg_ha}
    assert targets == {192.0}, targets
