"""The rate ECU (TC client) against a TC scripted frame by frame from the public message
layouts: it must connect, upload its DDOP, take setpoints and report actual values."""

from __future__ import annotations

import can
from fieldrx_edge.isobus import process_data as pdm
from fieldrx_edge.isobus.ddop import parse
from fieldrx_edge.isobus.j1939 import PGN_MACHINE_SELECTED_SPEED, PGN_PROCESS_DATA, Name
from fieldrx_edge.isobus.link import Message
from fieldrx_edge.isobus.network import Node, pump
from fieldrx_edge.isobus.rate_ecu import RateEcu
from fieldrx_edge.metering import LinearCalibration, shaft_rpm_for_rate

from tests.edge.isobus.test_network import Clock, channel, settle


def _scripted_tc():
    clock, ch = Clock(), channel()
    tc = Node(
        can.Bus(interface="virtual", channel=ch),
        Name(identity_number=1, function=130),
        0xF7,
        clock=clock,
        label="scripted-tc",
    )
    ecu_node = Node(
        can.Bus(interface="virtual", channel=ch),
        Name(identity_number=2, function=128),
        0x80,
        clock=clock,
        label="ecu",
    )
    ecu = RateEcu(ecu_node, LinearCalibration(), width_m=2.3, sections=1)
    got: list[Message] = []
    tc.handlers.append(got.append)
    tc.start()
    ecu_node.start()
    settle([tc, ecu_node], clock)
    return clock, tc, ecu_node, ecu, got


def _pd_from(got: list[Message], first: int) -> list[bytes]:
    return [m.data for m in got if m.pgn == PGN_PROCESS_DATA and m.data[0] == first]


def test_ecu_connects_to_a_scripted_tc_and_follows_setpoints():
    clock, tc, node, ecu, got = _scripted_tc()
    status = b"\xfe\xff\xff\xff\x00\x00\x00\xff"

    def step(seconds: float = 0.05) -> None:
        for _ in range(int(seconds / 0.01)):
            pump([tc, node])
            ecu.update(0.0)
            clock.t += 0.01
        pump([tc, node])

    tc.send(PGN_PROCESS_DATA, status)
    step()
    assert ecu.state == "wait_version"
    assert _pd_from(got, 0x00), "request version"
    tc.send(PGN_PROCESS_DATA, bytes((0x10, 4, 0xFF, 0x12, 0, 1, 16, 0)), node.address)
    step()
    assert _pd_from(got, 0x01), "request structure label"
    tc.send(PGN_PROCESS_DATA, b"\x11" + b"\xff" * 7, node.address)  # no stored pool
    step()
    req = _pd_from(got, 0x41)
    assert req and int.from_bytes(req[0][1:5], "little") == len(ecu.pool)
    tc.send(PGN_PROCESS_DATA, b"\x51\x00" + b"\xff" * 6, node.address)
    step(0.5)
    pool = [m for m in got if m.data[:1] == b"\x61"]
    assert pool and pool[0].data[1:] == ecu.pool
    ddop = parse(pool[0].data[1:])
    assert ddop.find(pdm.DDI_SETPOINT_MASS_PER_AREA, settable=True)
    tc.send(
        PGN_PROCESS_DATA,
        b"\x71\x00" + len(ecu.pool).to_bytes(4, "little") + b"\xff\xff",
        node.address,
    )
    step()
    assert _pd_from(got, 0x81)
    tc.send(PGN_PROCESS_DATA, b"\x91\x00\xff\xff\xff\xff\x00\xff", node.address)
    step()
    assert ecu.connected
    # setpoints: 700 kg/ha, section 1 on, 2 m/s
    tc.send(PGN_MACHINE_SELECTED_SPEED, pdm.mss_payload(2.0, 0.0))
    tc.send(PGN_PROCESS_DATA, pdm.encode(pdm.CMD_VALUE, 1, 6, 70_000), node.address)
    tc.send(
        PGN_PROCESS_DATA,
        pdm.encode(pdm.CMD_VALUE, 1, 290, pdm.condensed_work_state([True])),
        node.address,
    )
    step()
    want = shaft_rpm_for_rate(LinearCalibration(), 700.0, 2.3, 2.0)
    assert abs(ecu.target_rpm - want) < 1e-6
    # measurement by time: actual rate every 100 ms
    tc.send(PGN_PROCESS_DATA, pdm.encode(pdm.CMD_MEAS_TIME, 1, 7, 100), node.address)
    got.clear()
    for _ in range(50):
        tc.send(PGN_MACHINE_SELECTED_SPEED, pdm.mss_payload(2.0, 0.0))
        pump([tc, node])
        ecu.update(want)
        clock.t += 0.01
    vals = [pdm.decode(m.data) for m in got if m.data[0] & 0x0F == pdm.CMD_VALUE]
    rates = [v.value for v in vals if v.ddi == 7]
    assert 4 <= len(rates) <= 6
    assert abs(rates[-1] - 70_000) <= 5  # actual rate in mg/m^2 from the shaft speed
    # a setpoint for an element it does not have is refused with a PDACK
    tc.send(PGN_PROCESS_DATA, pdm.encode(pdm.CMD_VALUE, 9, 6, 1), node.address)
    step()
    acks = [m.data for m in got if m.data[0] & 0x0F == pdm.CMD_PDACK]
    assert acks and acks[-1][4] == 0x02
    # sections off: the shaft stops
    tc.send(PGN_PROCESS_DATA, pdm.encode(pdm.CMD_VALUE, 1, 290, 0), node.address)
    step()
    assert ecu.target_rpm == 0.0
    # the TC goes silent: after 6 s the ECU drops the connection, alarmed
    tc.send(PGN_PROCESS_DATA, pdm.encode(pdm.CMD_VALUE, 1, 290, 1), node.address)
    for _ in range(70):
        tc.send(PGN_MACHINE_SELECTED_SPEED, pdm.mss_payload(2.0, 0.0))
        step(0.1)
    assert "isobus_tc_lost" in ecu.alarms and ecu.state == "wait_tc" and ecu.target_rpm == 0.0
    tc.close()
    node.close()


def test_the_ecus_version_response_announces_its_section_control():
    """Before, the rate ECU answered a version request with no options at all although its
    pool has a settable DDI 290 and section elements."""
    from fieldrx_edge.isobus.pair import IsobusPair

    from tests.edge.jobfactory import trial_plot

    for sections, booms in ((16, 1), (130, 1)):
        pair = IsobusPair(trial_plot(), sections=sections)
        v = pair.ecu.version_response()
        assert v[0] == 0x10 and v[1] == pdm.TC_VERSION
        assert v[3] & pdm.SERVER_OPTION_SECTION_CONTROL
        assert (v[5], v[6]) == (booms, sections)
        pair.connect()
        pair.close()


def test_socketcand_buses_are_opened_with_tcp_nodelay():
    """Before, socketcand was opened without python-can's ``tcp_tune``: Nagle's algorithm
    held each set point behind the frame sent just before it (47 ms p95 measured)."""
    from fieldrx_edge.isobus.transport import parse_can_spec

    kw = parse_can_spec("socketcand:127.0.0.1:29536:can0")
    assert kw["tcp_tune"] is True and kw["interface"] == "socketcand"
