"""ISO 11783-10 DDOP binary format, and DDOPs over TP and ETP between the two roles."""

from __future__ import annotations

import dataclasses

import pytest
from fieldrx_edge.isobus import process_data as pdm
from fieldrx_edge.isobus.ddop import (
    DdopError,
    DeviceDescriptor,
    Element,
    encode_object,
    parse,
    rate_ecu_ddop,
)
from fieldrx_edge.isobus.j1939 import Name
from fieldrx_edge.isobus.pair import IsobusPair

from .jobfactory import trial_plot

NAME = Name(identity_number=42, manufacturer_code=1407, function=128)


def test_object_layouts_byte_by_byte():
    dd = rate_ecu_ddop(NAME, 2.3, sections=1)
    raw = dd.to_bytes()
    # DVC: tag, id 1, designator "FieldRx rate ECU" (16), version, NAME, serial, labels
    assert raw[:5] == b"DVC\x01\x00" and raw[5] == 16 and raw[6:22] == b"FieldRx rate ECU"
    i = raw.index(b"DPD")
    # DPD: id, DDI 6 little-endian, properties settable|default set, trigger on change
    assert raw[i + 5 : i + 7] == b"\x06\x00" and raw[i + 7] == 0x03 and raw[i + 8] == 0x08
    j = raw.index(b"DVP")
    assert raw[j + 5 : j + 9] == b"\x00\x00\x00\x00"  # offset 0
    again = parse(raw)
    assert again.to_bytes() == raw
    assert [type(o).__name__ for o in again.objects] == [type(o).__name__ for o in dd.objects]
    b = again.find(pdm.DDI_SETPOINT_MASS_PER_AREA, settable=True)[0]
    assert b.element_number == 1 and b.presentation is not None
    assert b.presentation.show(70_000) == "700.0 kg/ha"


@pytest.mark.parametrize(
    "mutate, msg",
    [
        (lambda raw: raw[:-3], "truncated"),
        (lambda raw: raw + b"XYZ\x01\x00", "unknown object type"),
        (lambda raw: raw + encode_object(rate_ecu_ddop(NAME, 2.3).elements[0]), "used twice"),
    ],
)
def test_malformed_pools_are_refused_with_a_reason(mutate, msg):
    raw = rate_ecu_ddop(NAME, 2.3).to_bytes()
    with pytest.raises(DdopError, match=msg):
        parse(mutate(raw))


def test_dangling_references_are_refused():
    dd = rate_ecu_ddop(NAME, 2.3)
    objs = [
        dataclasses.replace(o, children=o.children + [999]) if isinstance(o, Element) else o
        for o in dd.objects
    ]
    with pytest.raises(DdopError, match="missing child 999") as e:
        DeviceDescriptor(objs)
    assert e.value.object_id == 999


@pytest.mark.parametrize("sections, transport", [(1, "tp"), (130, "etp")])
def test_ddop_round_trip_between_client_and_server(sections, transport):
    job = trial_plot()
    pair = IsobusPair(job, sections=sections)
    size = len(pair.ecu.pool)
    assert (size <= 1785) == (transport == "tp")
    if transport == "etp":
        assert size >= 10_000
    pair.connect()
    c = pair.tc.client
    assert c is not None and bytes(c.pool) == pair.ecu.pool
    assert c.ddop is not None and c.ddop.to_bytes() == pair.ecu.pool
    assert len(c.ddop.sections()) == sections and c.n_sections == min(16, sections)
    assert pair.ecu_node.stats.transfers_tx == 1 and pair.tc_node.stats.transfers_rx == 1
    pair.close()


def test_tc_keeps_the_pool_and_a_reconnecting_client_skips_the_upload():
    job = trial_plot()
    pair = IsobusPair(job, sections=130)
    pair.connect()
    pair.ecu.restart()  # the implement restarts its connection procedure
    for _ in range(300):
        pair.tick()
        pair.clock.t += 0.01
        if pair.ecu.connected:
            break
    assert pair.ecu.connected
    assert pair.ecu_node.stats.transfers_tx == 1  # matched by structure label, not re-sent
    pair.close()


def test_structure_label_follows_the_pool():
    a = rate_ecu_ddop(NAME, 2.3, sections=1).device.structure_label
    assert a == rate_ecu_ddop(NAME, 2.3, sections=1).device.structure_label
    assert a != rate_ecu_ddop(NAME, 3.0, sections=1).device.structure_label
    assert a != rate_ecu_ddop(NAME, 2.3, sections=2).device.structure_label
    assert len(a) == 7 and a.startswith(b"FX")


def test_a_changed_implement_is_uploaded_again_not_served_from_the_store():
    job = trial_plot()
    pair = IsobusPair(job, sections=1)
    pair.connect()
    # the implement is reconfigured (other width) and reconnects under the same NAME
    ecu = pair.ecu
    ecu.ddop = rate_ecu_ddop(pair.ecu_node.name, 3.0, sections=1)
    ecu.pool = ecu.ddop.to_bytes()
    ecu.restart()
    for _ in range(300):
        pair.tick()
        pair.clock.t += 0.01
        if ecu.connected:
            break
    assert ecu.connected and pair.ecu_node.stats.transfers_tx == 2
    c = pair.tc.client
    assert c is not None and c.width_m == 3.0 and "isobus_width_mismatch" in pair.tc.alarms
    pair.close()
