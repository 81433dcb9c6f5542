"""A full job with the TC server driving the rate ECU over the virtual bus."""

from __future__ import annotations

import dataclasses

import numpy as np
from fieldrx_edge.isobus import process_data as pdm
from fieldrx_edge.isobus.pair import IsobusPair
from fieldrx_edge.sim.simulator import SimConfig, simulate

from tests.edge.jobfactory import trial_plot


class FakeDecision:
    """A metering decision as the runtime makes it (the fields the TC reads and writes)."""

    def __init__(self, rate: float = 700.0) -> None:
        self.target_rate_kg_ha, self.metering, self.speed_m_s = rate, True, 2.0
        self.target_rpm, self.reason = 80.0, "metering"
        self.alarms: list[str] = []


class Recorder:
    """Wraps the pair: records what the ECU had applied after every fix."""

    def __init__(self, pair: IsobusPair) -> None:
        self.pair = pair
        self.rows: list[tuple[str, bool, list[bool], float]] = []

    def step(self, t, d, y):
        sp = self.pair.step(t, d, y)
        self.rows.append((d.reason, d.metering, self.pair.ecu.sections(), sp))
        return sp


def test_tc_server_drives_the_rate_ecu_as_accurately_as_the_direct_run():
    job = trial_plot()
    cfg = SimConfig(seed=0, controller="ladrc")
    direct = simulate(job, cfg)
    pair = IsobusPair(job)
    pair.connect()
    rec = Recorder(pair)
    over = simulate(job, dataclasses.replace(cfg, implement=rec))
    pair.close()
    a, b = direct.cell_accuracy_pct, over.cell_accuracy_pct
    assert len(a) == len(b) == 70
    assert np.max(np.abs(a - b)) <= 1.0, np.max(np.abs(a - b))
    assert abs(a.mean() - b.mean()) <= 0.2
    assert over.cell_accuracy_pct.mean() >= 98.0
    # the client reported actual values back (time and distance triggers)
    c = pair.tc.client
    assert c is not None and c.values_rx > 100 and c.actual_rpm is not None
    assert pair.tc.setpoints_sent > 70
    # section switching at the field edge: off whenever the agent stops metering
    # (outside the field, edge ahead, implement raised), on while it meters
    for reason, metering, secs, sp in rec.rows:
        if metering:
            assert secs == [True], reason
        else:
            assert secs == [False] and sp == 0.0, reason
    reasons = {r for r, m, _, _ in rec.rows if not m}
    assert {"outside_field", "edge_ahead"} & reasons
    switches = sum(1 for p, q in zip(rec.rows, rec.rows[1:], strict=False) if p[2] != q[2])
    runs = len(set(job.swath))
    assert switches >= 2 * runs  # on at every swath start, off at every end


def test_client_loss_raises_the_alarm_and_pauses_metering():
    job = trial_plot()
    pair = IsobusPair(job)
    pair.connect()

    class D:  # a metering decision as the runtime makes it
        def __init__(self) -> None:
            self.target_rate_kg_ha, self.metering, self.speed_m_s = 700.0, True, 2.0
            self.target_rpm, self.reason, self.alarms = 80.0, "metering", []

    t = 0.0
    for _ in range(20):
        pair.step(t, D(), 80.0)
        t += 0.1
    assert pair.ecu.target_rpm > 0 and pair.tc.client is not None
    pair.drop_ecu()
    d = D()
    while t < 8.0:
        d = D()
        pair.step(t, d, 0.0)
        t += 0.1
    assert pair.tc.client is None
    assert "isobus_client_lost" in d.alarms and "isobus_no_client" in d.alarms
    assert d.metering is False and d.target_rpm == 0.0 and d.reason == "isobus_no_client"
    pair.close()


def test_a_valid_pool_this_tc_cannot_drive_is_activated_with_an_alarm_not_refused():
    """Before, a volume-rate pool with a kg/ha job and no density was refused as "errors in
    the DDOP" (activation error 0x01), after which clients give up for good; it is a valid
    pool, so it is activated, nothing is metered and the record says why."""
    from fieldrx_edge.isobus.ddop import DeviceDescriptor

    job = trial_plot()
    pair = IsobusPair(job)
    ecu = pair.ecu
    # the implement only offers volume per area: this job is kg/ha without a density
    objs = []
    for o in ecu.ddop.objects:
        if getattr(o, "ddi", None) == pdm.DDI_SETPOINT_MASS_PER_AREA:
            o = dataclasses.replace(o, ddi=pdm.DDI_SETPOINT_VOLUME_PER_AREA)
        objs.append(o)
    ecu.ddop = DeviceDescriptor(objs)
    ecu.pool = ecu.ddop.to_bytes()
    pair.connect(max_s=3.0)
    assert ecu.state == "connected" and "isobus_ddop_rejected" not in ecu.alarms
    c = pair.tc.client
    assert c is not None and not c.drivable and "DDI 1" in c.error
    assert "isobus_cannot_drive" in pair.tc.alarms and "isobus_wrong_ddop" not in pair.tc.alarms
    d = FakeDecision()
    pair.step(0.1, d, 0.0)
    assert d.metering is False and d.reason == "isobus_cannot_drive"
    assert "isobus_cannot_drive" in d.alarms and ecu.rate_mg_m2 == 0
    # garbage instead of a pool: refused at transfer, never a crash
    pair2 = IsobusPair(job)
    pair2.ecu.pool = b"DVC\x01\x00\x05abc"  # truncated
    try:
        pair2.connect(max_s=3.0)
    except RuntimeError:
        pass
    assert pair2.ecu.state == "rejected" and pair2.tc.client is None
    pair.close()
    pair2.close()


def test_tc_status_announces_the_running_task():
    import can
    from fieldrx_edge.isobus.j1939 import PGN_PROCESS_DATA, decode_id

    from tests.edge.isobus.test_network import channel

    ch = channel()
    pair = IsobusPair(trial_plot(), channel=ch)
    sniff = can.Bus(interface="virtual", channel=ch)
    pair.connect()

    def status_bytes() -> list[int]:
        out = []
        while (m := sniff.recv(0.0)) is not None:
            if decode_id(m.arbitration_id)[0] == PGN_PROCESS_DATA and m.data[0] == 0xFE:
                out.append(m.data[4])
        return out

    assert status_bytes() == [0]  # idle TC: task totals not active

    class D:
        target_rate_kg_ha, metering, speed_m_s, target_rpm, reason = 700.0, True, 2.0, 80.0, ""

        def __init__(self) -> None:
            self.alarms: list[str] = []

    pair.step(0.0, D(), 0.0)
    assert status_bytes() == [1]  # announced at once when the job starts
    pair.close()
    sniff.shutdown()


def test_a_lost_client_that_comes_back_is_driven_again():
    from fieldrx_edge.isobus.network import Node
    from fieldrx_edge.isobus.pair import ecu_name
    from fieldrx_edge.isobus.rate_ecu import RateEcu
    from fieldrx_edge.isobus.transport import open_bus
    from fieldrx_edge.metering import calibration_from_dict

    from tests.edge.isobus.test_network import channel

    job = trial_plot()
    ch = channel()
    pair = IsobusPair(job, channel=ch)
    pair.connect()

    class D:
        def __init__(self) -> None:
            self.target_rate_kg_ha, self.metering, self.speed_m_s = 700.0, True, 2.0
            self.target_rpm, self.reason, self.alarms = 80.0, "metering", []

    t = 0.0
    pair.drop_ecu()
    while t < 7.0:
        pair.step(t, D(), 0.0)
        t += 0.1
    assert "isobus_client_lost" in pair.tc.alarm_list()
    # the implement is plugged in again (same NAME): a new node on the bus
    node = Node(open_bus(f"virtual:{ch}"), ecu_name(), 0x80, pair.clock, "ecu2")
    ecu = RateEcu(node, calibration_from_dict(job.calibration), job.implement_width_m)
    node.start()
    d = D()
    while t < 12.0 and not (ecu.connected and ecu.target_rpm > 0):
        d = D()
        pair.step(t, d, 0.0)
        for _ in range(10):
            node.poll(0.0)
            ecu.update(0.0)
            pair.tc_node.poll(0.0)
            pair.tc.update()
        t += 0.1
    assert ecu.connected and ecu.target_rpm > 0
    assert pair.tc.client is not None and "isobus_client_lost" not in pair.tc.alarm_list()
    assert d.metering and "isobus_no_client" not in d.alarms
    node.close()
    pair.close()
