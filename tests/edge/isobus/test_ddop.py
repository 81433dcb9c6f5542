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

from tests.edge import ddop_strict
from tests.edge.jobfactory import trial_plot

NAME = Name(identity_number=42, manufacturer_code=1407, function=128)


def test_object_layouts_byte_by_byte():
    dd = rate_ecu_ddop(NAME, 2.3, sections=1)
    raw = dd.to_bytes()
    # DVC: tag, id 0, designator "FieldRx rate ECU" (16), version, NAME, serial, labels
    assert raw[:5] == b"DVC\x00\x00" and raw[5] == 16 and raw[6:22] == b"FieldRx rate ECU"
    # version 4: the extended structure label's length byte (0) closes the DVC
    dvc_end = raw.index(b"DVP")  # the presentations follow the DVC
    assert raw[dvc_end - 15 : dvc_end - 1] == dd.device.structure_label + pdm.LOCALIZATION_LABEL
    assert raw[dvc_end - 1] == 0
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


@pytest.mark.parametrize("sections", [1, 16, 130])
def test_the_pool_fieldrx_writes_passes_an_independent_strict_reader(sections):
    """Before, the DVC had id 1 and no version-4 extended-label byte, and element child
    lists named other elements: the independent reader (and AgIsoStack++) refused it."""
    raw = rate_ecu_ddop(NAME, 36.0, sections=sections).to_bytes()
    pool = ddop_strict.decode(raw, version=4)
    ((dvc_id, dvc),) = pool.of_type("DVC")
    assert dvc_id == 0 and dvc["ext"] == b""
    dets = dict(pool.of_type("DET"))
    device = [i for i, d in dets.items() if d["type"] == 1]
    assert len(device) == 1 and dets[device[0]]["parent"] == 0
    secs = [d for d in dets.values() if d["type"] == 4]
    assert len(secs) == sections
    assert all(pool.objects[dets[s["parent"]]["kids"][0]][0] == "DPD" for s in secs)


def _today_layout(raw: bytes, defect: str) -> bytes:
    """The pool with one of the three defects of the layout FieldRx wrote before."""
    if defect == "no_ext_label_byte":
        at = raw.index(b"DVP") - 1
        assert raw[at] == 0
        return raw[:at] + raw[at + 1 :]
    if defect == "dvc_id_1":
        return raw.replace(b"DVC\x00\x00", b"DVC\x01\x00", 1)
    # an element's child list names another element (the device element lists metering)
    dd = parse(raw)
    objs = list(dd.objects)
    dev = next(o for o in objs if isinstance(o, Element) and o.element_type == 1)
    meter = next(o for o in objs if isinstance(o, Element) and o.element_type == 2)
    objs[objs.index(dev)] = dataclasses.replace(dev, children=[meter.object_id])
    return b"".join(encode_object(o) for o in objs)


@pytest.mark.parametrize("defect", ["no_ext_label_byte", "dvc_id_1", "det_child_is_a_det"])
def test_pools_in_the_old_layout_are_refused_by_both_readers(defect):
    raw = _today_layout(rate_ecu_ddop(NAME, 2.3, sections=2).to_bytes(), defect)
    with pytest.raises(ddop_strict.StrictDdopError):
        ddop_strict.decode(raw, version=4)
    with pytest.raises(DdopError):
        parse(raw, version=4)


def test_version_3_pools_have_no_extended_label_byte():
    dd = rate_ecu_ddop(NAME, 2.3, sections=1)
    v3 = dd.to_bytes(version=3)
    assert len(v3) == len(dd.to_bytes()) - 1
    assert ddop_strict.decode(v3, version=3).order == ddop_strict.decode(dd.to_bytes()).order
    assert parse(v3, version=3).to_bytes(version=3) == v3
    with pytest.raises(DdopError):
        parse(v3, version=4)


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
