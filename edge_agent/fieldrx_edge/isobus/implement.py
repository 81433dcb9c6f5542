"""An ISOBUS implement in the motor's place: ``IsobusImplement`` lets the runtime drive
the Task Controller server (``tc_server``) as it drives ``motor.MotorLoop``.
"""

from __future__ import annotations

from typing import Any

from fieldrx_edge.isobus.tc_server import TaskControllerServer


class IsobusImplement:
    """The TC server standing where the agent's ``motor.MotorLoop`` stands: the runtime
    sets ``setpoint_rpm`` and reads ``rpm``/``duty`` as for a motor, and hands each
    decision to ``on_decision`` (rate, sections, speed go on the bus; the TC's alarms go
    into the record). ``run`` polls the bus until stopped."""

    def __init__(self, tc: TaskControllerServer) -> None:
        self.tc = tc
        self.setpoint_rpm = 0.0
        self.duty = 0.0  # the implement's own controller: not observable over ISOBUS
        self.overruns = 0
        self.decisions = 0

    @property
    def rpm(self) -> float:
        c = self.tc.client
        return c.actual_rpm if c is not None and c.actual_rpm is not None else 0.0

    def on_decision(self, d: Any) -> None:
        self.decisions += 1
        self.tc.command(d.target_rate_kg_ha, d.metering, d.speed_m_s)
        alarms = self.tc.alarm_list()
        c = self.tc.client
        if d.metering and (c is None or not c.drivable):
            d.metering = False  # nothing can meter: say so in the record
            d.target_rpm = 0.0
            d.reason = "isobus_no_client" if c is None else "isobus_cannot_drive"
        d.alarms.extend(a for a in alarms if a not in d.alarms)

    def run(self, stop: Any) -> None:
        node = self.tc.node
        node.start()
        while not stop.is_set():
            node.poll(0.002)
            self.tc.update()
