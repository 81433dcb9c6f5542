"""The TC server against a client scripted frame by frame with another vendor's kind of
DDOP: rate on a bin element, sections on the boom, 8 section elements."""

from __future__ import annotations

import can
from fieldrx_edge.isobus import process_data as pdm
from fieldrx_edge.isobus.ddop import (
    ELEMENT_BIN,
    ELEMENT_DEVICE,
    ELEMENT_FUNCTION,
    ELEMENT_SECTION,
    PROP_SETTABLE,
    TRIG_CHANGE,
    TRIG_DISTANCE,
    TRIG_TIME,
    Device,
    DeviceDescriptor,
    Element,
    Presentation,
    ProcessData,
    Property,
)
from fieldrx_edge.isobus.j1939 import PGN_PROCESS_DATA, PGN_WORKING_SET_MASTER, Name
from fieldrx_edge.isobus.link import Message
from fieldrx_edge.isobus.network import Node, pump
from fieldrx_edge.isobus.tc_server import TaskControllerServer

from tests.edge.isobus.test_network import Clock, channel, settle


def seeder_ddop(name: Name) -> DeviceDescriptor:
    objs = [
        Device(0, "Seeder 6m", "v2.1", name, "SN99", b"SEED001"),
        Presentation(50, 0, 0.01, 0, "kg/ha"),
        Element(10, ELEMENT_DEVICE, "Seeder", 0, 0, []),
        Element(11, ELEMENT_FUNCTION, "Boom", 1, 10, [20, 21, 22]),
        ProcessData(20, pdm.DDI_SETPOINT_CONDENSED_WORK_STATE, PROP_SETTABLE, TRIG_CHANGE, "SC"),
        ProcessData(21, pdm.DDI_ACTUAL_CONDENSED_WORK_STATE, 0, TRIG_CHANGE, "AC"),
        Property(22, pdm.DDI_ACTUAL_WORKING_WIDTH, 6000, "Width"),
        Element(12, ELEMENT_BIN, "Hopper", 7, 11, [30, 31]),
        ProcessData(30, pdm.DDI_SETPOINT_MASS_PER_AREA, PROP_SETTABLE, 0, "Rate", 50),
        ProcessData(31, pdm.DDI_ACTUAL_MASS_PER_AREA, 0, TRIG_TIME | TRIG_DISTANCE, "Act", 50),
    ]
    for k in range(8):
        objs.append(Element(100 + k, ELEMENT_SECTION, f"S{k + 1}", 20 + k, 11, []))
    return DeviceDescriptor(objs)


def test_tc_drives_a_foreign_client_by_its_own_element_numbers():
    clock, ch = Clock(), channel()
    tc_node = Node(can.Bus(interface="virtual", channel=ch), Name(1, function=130), 0xF7, clock)
    cl = Node(can.Bus(interface="virtual", channel=ch), Name(77, function=4), 0x90, clock)
    tc = TaskControllerServer(tc_node, implement_width_m=6.0)
    got: list[Message] = []
    cl.handlers.append(got.append)
    tc_node.start()
    cl.start()
    settle([tc_node, cl], clock)

    def run(s: float = 0.1) -> None:
        for _ in range(int(s / 0.01)):
            pump([tc_node, cl])
            tc.update()
            clock.t += 0.01
        pump([tc_node, cl])

    def reply(first: int) -> bytes:
        hits = [m.data for m in got if m.pgn == PGN_PROCESS_DATA and m.data[0] == first]
        assert hits, hex(first)
        return hits[-1]

    run()
    assert reply(0xFE)  # TC status
    tc_addr = tc_node.address
    pool = seeder_ddop(cl.name).to_bytes()
    cl.send(PGN_WORKING_SET_MASTER, b"\x01" + b"\xff" * 7)
    cl.send(PGN_PROCESS_DATA, b"\x00" + b"\xff" * 7, tc_addr)
    run()
    v = reply(0x10)
    assert v[1] == 4 and v[3] & 0x10 and v[6] == 16  # version 4, section control, 16 sections
    cl.send(PGN_PROCESS_DATA, b"\x01" + b"\xff" * 7, tc_addr)
    run()
    assert reply(0x11)[1:] == b"\xff" * 7  # nothing stored for this client
    cl.send(PGN_PROCESS_DATA, b"\x41" + len(pool).to_bytes(4, "little") + b"\xff" * 3, tc_addr)
    run()
    assert reply(0x51)[1] == 0
    cl.send(PGN_PROCESS_DATA, b"\x61" + pool, tc_addr)
    run(0.5)
    assert reply(0x71)[1] == 0
    cl.send(PGN_PROCESS_DATA, b"\x81\xff" + b"\xff" * 6, tc_addr)
    run()
    assert reply(0x91)[1] == 0
    c = tc.client
    assert c is not None and c.setpoint.element_number == 7 and c.work_state.element_number == 1
    assert c.n_sections == 8 and c.width_m == 6.0
    # measurements: actual rate on the bin element by time and distance
    meas = [pdm.decode(m.data) for m in got if m.data[0] & 0x0F in (4, 5)]
    assert {(p.command, p.element, p.ddi) for p in meas} >= {(4, 7, 7), (5, 7, 7)}
    got.clear()
    tc.command(650.0, True, 2.5)
    pump([tc_node, cl])
    vals = [pdm.decode(m.data) for m in got if m.data[0] & 0x0F == pdm.CMD_VALUE]
    assert (7, 6, 65_000) in {(p.element, p.ddi, p.value) for p in vals}
    ws = [p for p in vals if p.ddi == 290][-1]
    assert ws.element == 1 and pdm.sections_on(ws.value & 0xFFFFFFFF, 8) == [True] * 8
    assert (ws.value & 0xFFFFFFFF) >> 16 == 0xFFFF  # sections 9-16: not installed
    # the client reports its actual rate on the bin element: it reaches the TC
    cl.send(PGN_PROCESS_DATA, pdm.encode(pdm.CMD_VALUE, 7, 7, 64_000), tc_addr)
    pump([tc_node, cl])
    assert c.actual_rate_kg_ha == 640.0
    got.clear()
    tc.command(650.0, False, 2.5)  # the field edge: sections off, nothing else
    pump([tc_node, cl])
    vals = [pdm.decode(m.data) for m in got if m.data[0] & 0x0F == pdm.CMD_VALUE]
    assert [p.ddi for p in vals] == [290] and pdm.sections_on(vals[0].value, 8) == [False] * 8
    tc_node.close()
    cl.close()
