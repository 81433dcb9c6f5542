"""The TC server and the rate ECU on one python-can virtual bus, stepped in simulated time.

``simulate`` (``SimConfig.implement``) calls ``step`` once per GNSS fix: the decision goes
to the TC server, which puts the speed, rate and section frames on the bus; the ECU's
node reads them, the ECU computes its shaft target, and that target (not the agent's own)
drives the simulated motor until the next fix. The exchange is pumped until the bus is
quiet, so the run is deterministic; real frames and real protocol code are used, only the
clock is the simulation's.
"""

from __future__ import annotations

import itertools
import os
from typing import Any

from fieldrx_edge.isobus.implement import IsobusImplement
from fieldrx_edge.isobus.j1939 import FUNCTION_RATE_CONTROL, FUNCTION_TASK_CONTROLLER, Name
from fieldrx_edge.isobus.network import Node, pump
from fieldrx_edge.isobus.rate_ecu import RateEcu
from fieldrx_edge.isobus.tc_server import TaskControllerServer
from fieldrx_edge.isobus.transport import open_bus
from fieldrx_edge.metering import calibration_from_dict

_seq = itertools.count()

TC_ADDRESS = 0xF7  # the TC's preferred address (ISO 11783 preferred address of a TC)
ECU_ADDRESS = 0x80


class SimClock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def tc_name(instance: int = 0) -> Name:
    return Name(
        identity_number=0x1F1,
        manufacturer_code=0,
        function=FUNCTION_TASK_CONTROLLER,
        function_instance=instance,
    )


def ecu_name(identity: int = 0x2A2) -> Name:
    return Name(
        identity_number=identity,
        manufacturer_code=0,
        function=FUNCTION_RATE_CONTROL,
        device_class=4,
    )


class IsobusPair:
    """TC server (the agent) + rate ECU (the implement) on ``virtual:<channel>``."""

    def __init__(self, job: Any, channel: str | None = None, sections: int = 1) -> None:
        self.clock = SimClock()
        ch = channel or f"fieldrx-sim-{os.getpid()}-{next(_seq)}"
        self.tc_node = Node(open_bus(f"virtual:{ch}"), tc_name(), TC_ADDRESS, self.clock, "tc")
        self.ecu_node = Node(open_bus(f"virtual:{ch}"), ecu_name(), ECU_ADDRESS, self.clock, "ecu")
        self.tc = TaskControllerServer(self.tc_node, implement_width_m=job.implement_width_m)
        self.ecu = RateEcu(
            self.ecu_node, calibration_from_dict(job.calibration), job.implement_width_m, sections
        )
        self.implement = IsobusImplement(self.tc)
        self.t0 = 0.0
        self.ecu_alive = True

    def nodes(self) -> list[Node]:
        return [self.tc_node, self.ecu_node] if self.ecu_alive else [self.tc_node]

    def tick(self, actual_rpm: float = 0.0) -> None:
        pump(self.nodes())
        if self.ecu_alive:
            self.ecu.update(actual_rpm)
        self.tc.update()
        pump(self.nodes())

    def connect(self, max_s: float = 20.0, dt: float = 0.01) -> float:
        """Address claims and the client's connection; returns the simulated seconds used."""
        self.tc_node.start()
        self.ecu_node.start()
        t = 0.0
        while t < max_s:
            self.tick()
            if self.ecu.connected and self.tc.client is not None:
                self.tick()
                break
            t += dt
            self.clock.t += dt
        if not self.ecu.connected:
            raise RuntimeError(f"rate ECU did not connect (state {self.ecu.state})")
        self.t0 = self.clock.t
        return t

    def step(self, t: float, d: Any, actual_rpm: float) -> float:
        """One fix at simulation time ``t``: returns the ECU's shaft target (r/min)."""
        self.clock.t = self.t0 + t
        self.implement.on_decision(d)
        self.tick(actual_rpm)
        return self.ecu.target_rpm if self.ecu_alive else 0.0

    def drop_ecu(self) -> None:
        """The implement disappears (unplugged): its node stops answering."""
        self.ecu_alive = False
        self.ecu_node.close()

    def close(self) -> None:
        self.tc_node.close()
        self.ecu_node.close()
