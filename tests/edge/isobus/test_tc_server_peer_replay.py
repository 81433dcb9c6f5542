"""FieldRx's TC server against the recorded AgIsoStack++ task controller client.

The client's own frames come from the recorded trace (``data/isobus_peer/t2b_*``): its
NAME and address claim, working set master, client task, version request, its requests
for the Language Command and the structure label, the activation command; its pool is
``peer_sprayer.pool()``. Between them the client waits as the peer does (AgIsoStack++
``TaskControllerClient``: its start-up delay as recorded, then up to 6 s for the TC's
request of its version, up to 6 s for the Language Command, each step as soon as the TC
answers). Simulated time on python-can's virtual bus: any wait the TC adds shows.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import can
import pytest
from fieldrx_edge.isobus import process_data as pdm
from fieldrx_edge.isobus.j1939 import (
    PGN_ACKNOWLEDGE,
    PGN_ADDRESS_CLAIM,
    PGN_PROCESS_DATA,
    PGN_REQUEST,
    Name,
    decode_id,
)
from fieldrx_edge.isobus.link import Message
from fieldrx_edge.isobus.network import Node, pump
from fieldrx_edge.isobus.pair import tc_name
from fieldrx_edge.isobus.tc_mapping import RateUnits
from fieldrx_edge.isobus.tc_server import TaskControllerServer

from tests.edge import ddop_strict, peer_sprayer
from tests.edge.isobus.test_network import Clock, channel

TRACE = (
    Path(__file__).parents[1] / "data" / "isobus_peer" / "t2b_fieldrx_tc_vs_agiso_client.trace.txt"
)
PEER_WAIT_S = 6.0  # AgIsoStack++ SIX_SECOND_TIMEOUT_MS for the optional steps


@dataclass
class Frame:
    t: float
    who: str
    can_id: int
    data: bytes


def load_trace(path: Path = TRACE) -> list[Frame]:
    out = []
    for line in path.read_text().splitlines():
        parts = line.split()
        if len(parts) < 4 or "pgn=" not in line:
            continue
        data = []
        for tok in parts[3:]:
            if tok.startswith("pgn="):
                break
            data.append(int(tok, 16))
        out.append(Frame(float(parts[0]), parts[1], int(parts[2], 16), bytes(data)))
    return out


@dataclass
class Recorded:
    """The peer client's frames, picked from the trace by what they are."""

    frames: list[Frame]

    def first(self, pgn: int, head: bytes = b"") -> Frame:
        for f in self.frames:
            if f.who != "agiso_client":
                continue
            if decode_id(f.can_id)[0] == pgn and f.data.startswith(head):
                return f
        raise LookupError(f"no peer frame PGN 0x{pgn:04X} {head.hex()}")

    @property
    def claim(self) -> Frame:
        return self.first(PGN_ADDRESS_CLAIM)

    @property
    def startup_delay_s(self) -> float:
        return self.first(0xFE0D).t - self.claim.t


@dataclass
class PeerClient:
    """The recorded client, replayed step by step (module docstring)."""

    node: Node
    rec: Recorded
    pool: bytes
    state: str = "startup"
    t_state: float = 0.0
    t_claim: float = 0.0
    t_active: float | None = None
    last_task: float = -1e9
    got: list[Message] = field(default_factory=list)
    lang_requests: int = 0
    uploads: int = 0

    def __post_init__(self) -> None:
        self.node.handlers.append(self._on)

    def frame(self, f: Frame) -> None:
        pgn, _sa, da, prio = decode_id(f.can_id)
        self.node.send(pgn, f.data, da, prio)

    def start(self) -> None:
        self.node.start()
        self.t_claim = self.node.clock()
        self._to("startup")

    def _to(self, state: str) -> None:
        self.state, self.t_state = state, self.node.clock()

    def pd(self, data: bytes) -> None:
        self.node.send(PGN_PROCESS_DATA, data, self.tc, 6)

    @property
    def tc(self) -> int:
        return decode_id(self.rec.first(PGN_PROCESS_DATA, b"\xff").can_id)[2]

    def update(self) -> None:
        now = self.node.clock()
        waited = now - self.t_state
        if self.state == "startup" and now - self.t_claim >= self.rec.startup_delay_s:
            self.frame(self.rec.first(0xFE0D))
            self.frame(self.rec.first(PGN_PROCESS_DATA, b"\xff"))
            self.last_task = now
            self.frame(self.rec.first(PGN_PROCESS_DATA, b"\x00"))
            self._to("wait_version")
        elif self.state == "wait_server_version_request" and waited >= PEER_WAIT_S:
            self._request_language()  # "not required, so proceeding anyway"
        elif self.state == "wait_language" and waited >= PEER_WAIT_S:
            self._request_structure()
        if self.state != "startup" and now - self.last_task >= 2.0:
            self.frame(self.rec.first(PGN_PROCESS_DATA, b"\xff"))
            self.last_task = now

    def _request_language(self) -> None:
        self.lang_requests += 1
        self.frame(self.rec.first(PGN_REQUEST, b"\x0f\xfe"))  # to the TC
        self._to("wait_language")

    def _request_structure(self) -> None:
        self.frame(self.rec.first(PGN_PROCESS_DATA, b"\x01"))
        self._to("wait_structure")

    def _on(self, m: Message) -> None:
        self.got.append(m)
        if m.pgn == pdm.PGN_LANGUAGE_COMMAND and self.state == "wait_language":
            self._request_structure()
        if m.pgn != PGN_PROCESS_DATA or m.da != self.node.address:
            return
        head = m.data[0]
        if head == 0x10 and self.state == "wait_version":
            self._to("wait_server_version_request")
        elif head == 0x00 and self.state == "wait_server_version_request":
            self.pd(pdm.version_message(0x1F, 1, 16))
            self._request_language()
        elif head == 0x11 and self.state == "wait_structure":
            dvc = ddop_strict.decode(self.pool).objects[0][1]
            if m.data[1:8] == dvc["structure"]:
                self.pd(b"\x21" + b"\xff" * 7)
                self._to("wait_localization")
            else:
                self._request_transfer()
        elif head == 0x31 and self.state == "wait_localization":
            dvc = ddop_strict.decode(self.pool).objects[0][1]
            if m.data[1:8] == dvc["localization"]:
                self._activate()
            else:
                self._request_transfer()
        elif head == 0x51 and self.state == "wait_transfer_ok" and m.data[1] == 0:
            self.uploads += 1
            self.node.send(PGN_PROCESS_DATA, b"\x61" + self.pool, self.tc, 6)
            self._to("wait_transfer")
        elif head == 0x71 and self.state == "wait_transfer" and m.data[1] == 0:
            self._activate()
        elif head == 0x91 and self.state == "wait_activate":
            self._to("active" if m.data[1] == 0 else "refused")
            self.t_active = self.node.clock()

    def _request_transfer(self) -> None:
        self.pd(b"\x41" + len(self.pool).to_bytes(4, "little") + b"\xff" * 3)
        self._to("wait_transfer_ok")

    def _activate(self) -> None:
        self.frame(self.rec.first(PGN_PROCESS_DATA, b"\x81"))
        self._to("wait_activate")


class Bench:
    """The TC server (FieldRx) and the recorded peer client on one virtual bus."""

    def __init__(self, units: RateUnits, width_m: float = 36.576) -> None:
        self.clock = Clock()
        self.ch = channel()
        self.rec = Recorded(load_trace())
        self.tc_node = self._node(tc_name(), 0xF7)
        self.tc = TaskControllerServer(self.tc_node, implement_width_m=width_m, units=units)
        self.peer = self._peer()

    def _node(self, name: Name, addr: int) -> Node:
        bus = can.Bus(interface="virtual", channel=self.ch, receive_own_messages=False)
        return Node(bus, name, addr, self.clock, label=f"n{addr:02X}")

    def _peer(self) -> PeerClient:
        claim = self.rec.claim
        node = self._node(Name.from_bytes(claim.data), decode_id(claim.can_id)[1])
        return PeerClient(node, self.rec, peer_sprayer.pool())

    def run(self, seconds: float, until: str | None = None, dt: float = 0.01) -> None:
        for _ in range(int(seconds / dt)):
            pump([self.tc_node, self.peer.node])
            self.tc.update()
            self.peer.update()
            pump([self.tc_node, self.peer.node])
            if until is not None and self.peer.state == until:
                return
            self.clock.t += dt

    def connect(self) -> None:
        self.tc_node.start()
        self.run(0.5)
        self.peer.start()
        self.run(40.0, until="active")
        self.run(0.1)  # the TC's first update after activation sets up measurements

    def close(self) -> None:
        self.tc_node.close()
        self.peer.node.close()

    def sent_by_tc(self) -> list[pdm.PD]:
        return [
            pdm.decode(m.data)
            for m in self.peer.got
            if m.pgn == PGN_PROCESS_DATA and m.sa == self.tc_node.address and len(m.data) == 8
        ]


@pytest.fixture
def bench():
    b = Bench(RateUnits("l/ha"))
    yield b
    b.close()


def test_the_recorded_client_is_activated_with_no_wait_of_the_tcs_own(bench):
    """Before, the peer waited 6 s for a version request the TC never sent and 6 s on its
    unanswered Language Command request: ~12 s of the connection were the TC's."""
    bench.connect()
    p = bench.peer
    assert p.state == "active", p.state
    assert p.rec.startup_delay_s == pytest.approx(7.615, abs=0.01)
    tc_wait = p.t_active - p.t_claim - p.rec.startup_delay_s
    assert tc_wait < 1.0, f"the TC added {tc_wait:.2f} s"
    assert p.lang_requests == 1 and p.uploads == 1
    c = bench.tc.client
    assert c is not None and c.version == 4 and c.drivable and c.kind == "volume"
    assert c.setpoint.element_number == 3 and c.work_state.element_number == 2


def test_the_tc_requests_the_clients_version_right_after_its_own_answer(bench):
    bench.connect()
    tc_frames = [m.data for m in bench.peer.got if m.pgn == PGN_PROCESS_DATA and m.da != 0xFF]
    i = next(k for k, d in enumerate(tc_frames) if d[0] == 0x10)
    assert tc_frames[i][1] == 4 and tc_frames[i][3] & pdm.SERVER_OPTION_SECTION_CONTROL
    assert tc_frames[i + 1] == b"\x00" + b"\xff" * 7  # request version, at once


def test_the_language_command_is_answered_to_a_destination_specific_request(bench):
    bench.connect()
    lang = [m for m in bench.peer.got if m.pgn == pdm.PGN_LANGUAGE_COMMAND]
    assert len(lang) == 1 and lang[0].data == pdm.LANGUAGE_COMMAND
    assert lang[0].sa == bench.tc_node.address and lang[0].da == 0xFF
    assert lang[0].data[:2] == b"en" and lang[0].data[2] >> 6 == 1  # decimal point


def test_unsupported_destination_specific_requests_are_nacked_global_ones_not(bench):
    bench.connect()
    peer = bench.peer
    peer.got.clear()
    tc = bench.tc_node.address
    peer.node.request(0xFEE6, tc)  # time/date: not provided by FieldRx
    peer.node.request(0xFEE6)  # the same to global: no answer at all
    pump([bench.tc_node, peer.node])
    acks = [m for m in peer.got if m.pgn == PGN_ACKNOWLEDGE]
    assert len(acks) == 1
    a = acks[0]
    assert a.sa == tc and a.da == 0xFF
    assert a.data == bytes((0x01, 0xFF, 0xFF, 0xFF, peer.node.address, 0xE6, 0xFE, 0x00))


def test_a_reconnecting_client_reuses_the_held_pool_by_both_labels(bench):
    """Before, the localization label was answered 0xFF x 7 even for a held pool, so the
    client uploaded its whole pool again at every reconnection."""
    bench.connect()
    peer = bench.peer
    assert peer.uploads == 1
    peer.got.clear()
    peer._request_structure()  # the client restarts its connection (same NAME and pool)
    bench.run(5.0, until="active")
    assert peer.state == "active" and peer.uploads == 1
    replies = {m.data[0]: m.data for m in peer.got if m.pgn == PGN_PROCESS_DATA}
    dvc = ddop_strict.decode(peer.pool).objects[0][1]
    assert replies[0x11][1:8] == dvc["structure"]
    assert replies[0x31][1:8] == dvc["localization"] == b"en\x50\x00\x55\x55\xff"


def test_the_tc_asks_who_claimed_before_it_started():
    """Before, no Request for Address Claimed was sent: nodes that claimed earlier stayed
    unknown (no NAME for their address, so no stored pool could be matched)."""
    clock, ch = Clock(), channel()
    early = Node(can.Bus(interface="virtual", channel=ch), Name(5, function=4), 0x80, clock)
    early.start()
    for _ in range(30):
        pump([early])
        clock.t += 0.01
    assert early.claimed
    sniff = can.Bus(interface="virtual", channel=ch)
    tc = Node(can.Bus(interface="virtual", channel=ch), tc_name(), 0xF7, clock)
    tc.start()
    first = sniff.recv(1.0)
    assert first is not None
    pgn, sa, da, _ = decode_id(first.arbitration_id)
    assert (pgn, sa, da, bytes(first.data)) == (PGN_REQUEST, 0xFE, 0xFF, b"\x00\xee\x00")
    pump([tc, early])
    assert tc.peers.get(0x80) == early.name
    for n in (tc, early):
        n.close()
    sniff.shutdown()


def test_width_as_process_data_is_read_and_checked(bench):
    """Before, a working width given as a DPD (DDI 67 on the boom) was never read: a
    36.6 m boom against a 2.3 m job raised nothing."""
    bench.tc.implement_width_m = 2.3
    bench.connect()
    asks = [p for p in bench.sent_by_tc() if p.command == pdm.CMD_REQUEST_VALUE]
    assert (2, pdm.DDI_ACTUAL_WORKING_WIDTH) in {(p.element, p.ddi) for p in asks}
    peer = bench.peer
    peer.pd(pdm.encode(pdm.CMD_VALUE, 2, pdm.DDI_ACTUAL_WORKING_WIDTH, 36_576))
    pump([bench.tc_node, peer.node])
    assert bench.tc.client.width_m == pytest.approx(36.576)
    assert "isobus_width_mismatch" in bench.tc.alarms
    # the AgIsoStack++ example answers 0 for DDI 67 (it tracks no width): said, not checked
    peer.pd(pdm.encode(pdm.CMD_VALUE, 2, pdm.DDI_ACTUAL_WORKING_WIDTH, 0))
    pump([bench.tc_node, peer.node])
    assert "isobus_width_unknown" in bench.tc.alarms


def test_default_process_data_work_state_and_control_states_are_honoured(bench):
    bench.connect()
    sent = bench.sent_by_tc()
    asks = {(p.element, p.ddi) for p in sent if p.command == pdm.CMD_REQUEST_VALUE}
    assert {(0, 0xDFFF), (2, 160), (3, 158)} <= asks
    peer, tc = bench.peer, bench.tc
    peer.got.clear()
    tc.command(150.0, True, 2.0)  # l/ha job: straight to DDI 1
    pump([bench.tc_node, peer.node])
    vals = {(p.element, p.ddi): p.value for p in bench.sent_by_tc() if p.command == 3}
    assert vals[(3, 1)] == 1_500_000 and vals[(2, 289)] == 1
    assert vals[(2, 290)] & 0xFFFFFFFF == 0x55555555
    # the operator puts section control to manual on the implement: the TC stops switching
    peer.pd(pdm.encode(pdm.CMD_VALUE, 2, pdm.DDI_SECTION_CONTROL_STATE, 0))
    pump([bench.tc_node, peer.node])
    assert "isobus_sections_manual" in tc.alarms
    peer.got.clear()
    bench.clock.t += 1.5
    tc.command(150.0, False, 2.0)
    pump([bench.tc_node, peer.node])
    ddis = [p.ddi for p in bench.sent_by_tc() if p.command == 3]
    assert 290 not in ddis and 289 in ddis
    # prescription control to manual: no rate setpoints either
    peer.pd(pdm.encode(pdm.CMD_VALUE, 3, pdm.DDI_PRESCRIPTION_CONTROL_STATE, 0))
    pump([bench.tc_node, peer.node])
    peer.got.clear()
    bench.clock.t += 1.5
    tc.command(120.0, True, 2.0)
    pump([bench.tc_node, peer.node])
    assert 1 not in [p.ddi for p in bench.sent_by_tc() if p.command == 3]
    assert "isobus_rate_manual" in tc.alarms
    # both back to auto: the TC drives them again at the next fix, without waiting
    for el, ddi in ((2, pdm.DDI_SECTION_CONTROL_STATE), (3, pdm.DDI_PRESCRIPTION_CONTROL_STATE)):
        peer.pd(pdm.encode(pdm.CMD_VALUE, el, ddi, 1))
    pump([bench.tc_node, peer.node])
    peer.got.clear()
    bench.clock.t += 0.1
    tc.command(120.0, True, 2.0)
    pump([bench.tc_node, peer.node])
    vals = {(p.element, p.ddi): p.value for p in bench.sent_by_tc() if p.command == 3}
    assert vals[(3, 1)] == 1_200_000 and vals[(2, 290)] & 0xFFFFFFFF == 0x55555555
    assert not {"isobus_sections_manual", "isobus_rate_manual"} & tc.alarms
    from fieldrx_edge.protocol import ALARMS

    assert set(tc.alarm_list()) <= set(ALARMS)  # telemetry records accept them


def test_a_kg_ha_job_with_the_products_density_drives_the_volume_implement():
    b = Bench(RateUnits("kg/ha", density_kg_l=1.28))  # UAN 28 %
    try:
        b.connect()
        assert b.peer.state == "active" and b.tc.client.drivable
        b.peer.got.clear()
        b.tc.command(192.0, True, 2.0)  # 192 kg/ha / 1.28 kg/l = 150 l/ha
        pump([b.tc_node, b.peer.node])
        vals = {(p.element, p.ddi): p.value for p in b.sent_by_tc() if p.command == 3}
        assert vals[(3, 1)] == 1_500_000
        b.peer.pd(pdm.encode(pdm.CMD_VALUE, 3, pdm.DDI_ACTUAL_VOLUME_PER_AREA, 1_000_000))
        pump([b.tc_node, b.peer.node])
        assert b.tc.client.actual_rate_kg_ha == pytest.approx(128.0)
    finally:
        b.close()
