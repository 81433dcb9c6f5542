"""Robustness on the bus during a job: junk frames, an address
conflict, bus-off, a silent TC. Logged and alarmed, never a crash; metering stops safely."""

from __future__ import annotations

import dataclasses
import random

import can
import numpy as np
from fieldrx_edge.isobus.j1939 import Name, encode_id
from fieldrx_edge.isobus.network import Node
from fieldrx_edge.isobus.pair import IsobusPair
from fieldrx_edge.sim.simulator import SimConfig, simulate

from tests.edge.jobfactory import trial_plot


class D:
    """A metering decision as the runtime makes it."""

    def __init__(self) -> None:
        self.target_rate_kg_ha, self.metering, self.speed_m_s = 700.0, True, 2.0
        self.target_rpm, self.reason, self.alarms = 80.0, "metering", []


def _run(pair: IsobusPair, t0: float, t1: float, hook=None) -> tuple[float, D]:
    t, d = t0, D()
    while t < t1:
        if hook is not None:
            hook(t)
        d = D()
        pair.step(t, d, 80.0 if pair.ecu.target_rpm else 0.0)
        t += 0.1
    return t, d


def test_junk_frames_during_a_job_change_nothing():
    job = trial_plot()
    cfg = SimConfig(seed=0, controller="ladrc")
    direct = simulate(job, cfg)
    ch = f"robust-junk-{random.randrange(1 << 30)}"
    pair = IsobusPair(job, channel=ch)
    pair.connect()
    noise = can.Bus(interface="virtual", channel=ch)
    rng = random.Random(3)
    tc_addr, ecu_addr = pair.tc_node.address, pair.ecu_node.address

    class Noisy:
        def step(self, t, d, y):
            for _ in range(3):  # random PGNs, truncated TP/ETP frames, stray data transfers
                pgn = rng.choice([0xEC00, 0xEB00, 0xC800, 0xC700, 0xCB00, 0xEE00, 0xEA00, 0xFE0D])
                da = rng.choice([tc_addr, ecu_addr, 0xFF])
                data = bytes(rng.randrange(256) for _ in range(rng.randrange(0, 9)))
                if pgn == 0xCB00 and len(data) == 8:
                    continue  # a well-formed process data frame from a stranger is not junk
                noise.send(
                    can.Message(
                        arbitration_id=encode_id(pgn, 0x33, da), data=data, is_extended_id=True
                    )
                )
            return pair.step(t, d, y)

    over = simulate(job, dataclasses.replace(cfg, implement=Noisy()))
    noise.shutdown()
    assert np.max(np.abs(direct.cell_accuracy_pct - over.cell_accuracy_pct)) <= 1.0
    assert pair.tc_node.stats.malformed + pair.ecu_node.stats.malformed > 100
    assert pair.tc_node.stats.handler_errors == 0 and pair.ecu_node.stats.handler_errors == 0
    pair.close()


def test_tc_address_taken_mid_job_ecu_follows_the_tc_name():
    job = trial_plot()
    ch = f"robust-addr-{random.randrange(1 << 30)}"
    pair = IsobusPair(job, channel=ch)
    pair.connect()
    t, _ = _run(pair, 0.0, 2.0)
    old = pair.tc_node.address
    # a node with a higher-priority NAME claims the TC's address
    intruder = Node(
        can.Bus(interface="virtual", channel=ch),
        Name(identity_number=1, function=130, self_configurable=False),
        old,
        clock=pair.clock,
        label="intruder",
    )
    intruder.start()
    pair.tc_node.poll(0.0)
    t, d = _run(pair, t, t + 10.0, hook=lambda _t: intruder.poll(0.0) and None)
    assert pair.tc_node.address not in (old, 0xFE) and pair.tc_node.claimed
    assert pair.ecu.tc_addr == pair.tc_node.address
    assert pair.ecu.connected and pair.ecu.target_rpm > 0
    assert pair.ecu.tc_losses == 0  # followed at once, never dropped
    assert "isobus_address_lost" in d.alarms
    intruder.close()
    pair.close()


def test_bus_off_at_the_tc_stops_metering_at_the_ecu():
    job = trial_plot()
    pair = IsobusPair(job)
    pair.connect()
    t, _ = _run(pair, 0.0, 2.0)
    assert pair.ecu.target_rpm > 0
    pair.tc_node.bus.shutdown()  # the TC's CAN interface goes bus-off
    t, d = _run(pair, t, t + 1.5)
    # no machine selected speed for 1 s: the ECU stops the shaft long before the
    # 6 s TC time-out
    assert pair.ecu.target_rpm == 0.0 and pair.ecu.state == "connected"
    t, d = _run(pair, t, t + 6.0)
    assert "isobus_bus_off" in d.alarms
    assert pair.ecu.target_rpm == 0.0 and "isobus_tc_lost" in pair.ecu.alarms
    pair.ecu_node.close()
