"""The rate ECU: FieldRx's metering loop as an ISO 11783-10 Task Controller client.

Connection procedure (ISO 11783-10 Annex B as implemented by AgIsoStack++'s
``TaskControllerClient`` state machine): wait for a TC status message -> working set
master (PGN 0xFE0D, one member) -> client task every 2 s -> request the TC's version ->
request the structure label and, when it matches, the localization label (a TC that
already holds this pool answers both, the upload is skipped) -> request object-pool
transfer (size) -> transfer the pool (TP or ETP) -> activate -> connected. Any step that
gets no answer within 6 s starts again from the beginning; an activation refused by the
TC is logged and alarmed and metering stays off.

Connected, the ECU accepts from whatever TC it connected to: value / set-value-and-ack
commands for the setpoint mass per area (DDI 6) and the setpoint condensed work state
(DDI 290), request-value, and measurement commands (time interval, distance interval,
change threshold) for the actual rate (DDI 7), shaft speed (DDI 390) and the actual
condensed work state (DDI 161). Ground speed comes from the bus's machine selected speed
(PGN 0xF022), as any implement ECU takes it from the tractor.

The shaft target is the same function the direct agent uses (``metering.shaft_rpm_for_rate``,
seed 001 eq. 1-3), clamped to the calibration's range. It is 0 when: no TC is connected,
the TC status stopped for 6 s, all sections are off, the rate is 0, or no speed for 1 s.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from fieldrx_edge.isobus import process_data as pdm
from fieldrx_edge.isobus.ddop import rate_ecu_ddop
from fieldrx_edge.isobus.j1939 import (
    GLOBAL_ADDRESS,
    PGN_MACHINE_SELECTED_SPEED,
    PGN_PROCESS_DATA,
    PGN_WORKING_SET_MASTER,
)
from fieldrx_edge.isobus.link import Message
from fieldrx_edge.isobus.network import Node
from fieldrx_edge.metering import rate_for_shaft_rpm, shaft_rpm_for_rate

log = logging.getLogger(__name__)

METER_ELEMENT = 1
STEP_TIMEOUT_S = 6.0
TC_TIMEOUT_S = 6.0  # ISO 11783-10: the TC status is sent every 2 s
SPEED_TIMEOUT_S = 1.0
CLIENT_TASK_PERIOD_S = 2.0

ERR_NOT_SUPPORTED = 0x01
ERR_INVALID_ELEMENT = 0x02
ERR_DDI_NOT_SUPPORTED = 0x04
ERR_NOT_SETTABLE = 0x10


@dataclass
class _Trigger:
    time_ms: int = 0
    distance_mm: int = 0
    change: int = 0
    last_t: float = 0.0
    last_dist_m: float = 0.0
    last_value: int | None = None


class RateEcu:
    """See module docstring. Drive it with ``update(actual_rpm)`` after ``node.poll``."""

    SETTABLE = (pdm.DDI_SETPOINT_MASS_PER_AREA, pdm.DDI_SETPOINT_CONDENSED_WORK_STATE)
    MEASURED = (
        pdm.DDI_ACTUAL_MASS_PER_AREA,
        pdm.DDI_ACTUAL_REVOLUTIONS,
        pdm.DDI_ACTUAL_CONDENSED_WORK_STATE,
        pdm.DDI_SETPOINT_MASS_PER_AREA,
        pdm.DDI_SETPOINT_CONDENSED_WORK_STATE,
    )

    def __init__(
        self,
        node: Node,
        calibration: Any,
        width_m: float,
        sections: int = 1,
        clock: Callable[[], float] | None = None,
    ) -> None:
        self.node = node
        self.cal = calibration
        self.width_m = float(width_m)
        self.n_sections = max(1, min(16, int(sections)))
        self.clock = clock or node.clock
        self.ddop = rate_ecu_ddop(node.name, width_m, sections)
        self.pool = self.ddop.to_bytes()
        self.state = "wait_tc"
        self.state_t = self.clock()
        self.tc_addr: int | None = None
        self.tc_name: Any = None
        self.tc_losses = 0
        self.tc_version: int | None = None
        self.last_tc_status_t = -1e9
        self.rate_mg_m2 = 0
        self.work_state = pdm.condensed_work_state([False] * self.n_sections)
        self.speed_m_s = 0.0
        self.speed_t = -1e9
        self.distance_m = 0.0
        self._last_update_t = self.clock()
        self.actual_rpm = 0.0
        self.target_rpm = 0.0
        self.triggers: dict[int, _Trigger] = {}
        self.alarms: set[str] = set()
        self.setpoints_rx = 0
        self.last_setpoint_t: float | None = None
        self._last_task_t = -1e9
        self._transfer: Any = None
        node.handlers.append(self._on_message)

    # -- helpers -------------------------------------------------------------

    def _send_pd(self, data: bytes) -> None:
        if self.tc_addr is not None:
            self.node.send(PGN_PROCESS_DATA, data, self.tc_addr, 5)

    def _to(self, state: str) -> None:
        log.debug("[%s] %s -> %s", self.node.label, self.state, state)
        self.state = state
        self.state_t = self.clock()

    def restart(self) -> None:
        """Start the connection procedure again (the implement was reset or reconfigured)."""
        self.tc_addr = None
        self.tc_name = None
        self.triggers.clear()
        self._to("wait_tc")

    @property
    def connected(self) -> bool:
        return self.state == "connected"

    def sections(self) -> list[bool]:
        return pdm.sections_on(self.work_state, self.n_sections)

    def rate_kg_ha(self) -> float:
        return self.rate_mg_m2 / pdm.MG_M2_PER_KG_HA

    def _value(self, ddi: int) -> int:
        if ddi == pdm.DDI_ACTUAL_REVOLUTIONS:
            return int(round(self.actual_rpm * pdm.RPM_BITS))
        if ddi == pdm.DDI_ACTUAL_MASS_PER_AREA:
            rate = rate_for_shaft_rpm(self.cal, self.actual_rpm, self.width_m, self.speed_m_s)
            return int(round(max(0.0, rate) * pdm.MG_M2_PER_KG_HA))
        if ddi == pdm.DDI_ACTUAL_CONDENSED_WORK_STATE:
            on = self.target_rpm > 0.0
            return pdm.condensed_work_state([s and on for s in self.sections()])
        if ddi == pdm.DDI_SETPOINT_MASS_PER_AREA:
            return self.rate_mg_m2
        return self.work_state

    # -- receive ---------------------------------------------------------------

    def _on_message(self, msg: Message) -> None:
        if msg.pgn == PGN_MACHINE_SELECTED_SPEED:
            v = pdm.mss_speed(msg.data)
            if v is not None:
                self.speed_m_s, self.speed_t = v, msg.t
            return
        if msg.pgn != PGN_PROCESS_DATA or len(msg.data) < 8:
            return
        d = msg.data
        cmd = d[0] & 0x0F
        if cmd == pdm.CMD_STATUS and msg.da == GLOBAL_ADDRESS:
            self._on_tc_status(msg)
            return
        if msg.sa != self.tc_addr:
            return
        sub = d[0] >> 4
        if cmd == pdm.CMD_TECHNICAL:
            if sub == pdm.TECH_VERSION and self.state == "wait_version":
                self.tc_version = d[1]
                self._request_label()
            elif sub == pdm.TECH_REQUEST_VERSION:
                self._send_pd(self.version_response())
            return
        if cmd == pdm.CMD_DEVICE_DESCRIPTOR:
            self._on_dd(sub, d)
            return
        if self.state == "connected":
            self._on_process_value(cmd, pdm.decode(d))

    def _on_tc_status(self, msg: Message) -> None:
        """A task controller's status broadcast: adopt the first TC, follow it if it moves."""
        if self.tc_addr is not None and msg.sa != self.tc_addr:
            name = self.node.peers.get(msg.sa)
            if name is None or name != self.tc_name:
                return  # another TC on the bus; we stay with ours
            # our TC re-claimed another address (J1939-81 contention): follow its NAME
            log.warning("[%s] TC moved 0x%02X -> 0x%02X", self.node.label, self.tc_addr, msg.sa)
            self.tc_addr = msg.sa
        if self.tc_addr is None:
            self.tc_addr = msg.sa
            self.tc_name = self.node.peers.get(msg.sa)
        self.last_tc_status_t = msg.t
        self.alarms.discard("isobus_tc_lost")

    def _on_process_value(self, cmd: int, pd: pdm.PD) -> None:
        """A value, request or measurement command from our TC once connected."""
        if cmd in (pdm.CMD_VALUE, pdm.CMD_SET_VALUE_ACK):
            err = self._set(pd)
            if err or cmd == pdm.CMD_SET_VALUE_ACK:
                self._pdack(pd, err)
        elif cmd == pdm.CMD_REQUEST_VALUE:
            if self._refuse_unmeasured(pd):
                return
            self._send_pd(pdm.encode(pdm.CMD_VALUE, METER_ELEMENT, pd.ddi, self._value(pd.ddi)))
        elif cmd in (pdm.CMD_MEAS_TIME, pdm.CMD_MEAS_DISTANCE, pdm.CMD_MEAS_CHANGE):
            if self._refuse_unmeasured(pd):
                return
            tr = self.triggers.setdefault(pd.ddi, _Trigger(last_t=self.clock()))
            if cmd == pdm.CMD_MEAS_TIME:
                tr.time_ms = max(0, pd.value)
            elif cmd == pdm.CMD_MEAS_DISTANCE:
                tr.distance_mm = max(0, pd.value)
                tr.last_dist_m = self.distance_m
            else:
                tr.change = max(0, pd.value)
        elif cmd != pdm.CMD_PDACK:
            self._pdack(pd, ERR_NOT_SUPPORTED)

    def _refuse_unmeasured(self, pd: pdm.PD) -> bool:
        """NACK (and return True for) a request about anything but the meter's measured DDIs."""
        if pd.element != METER_ELEMENT or pd.ddi not in self.MEASURED:
            self._pdack(
                pd,
                ERR_INVALID_ELEMENT if pd.element != METER_ELEMENT else ERR_DDI_NOT_SUPPORTED,
            )
            return True
        return False

    def _set(self, pd: pdm.PD) -> int:
        if pd.element != METER_ELEMENT:
            return ERR_INVALID_ELEMENT
        if pd.ddi == pdm.DDI_SETPOINT_MASS_PER_AREA:
            self.rate_mg_m2 = max(0, pd.value)
        elif pd.ddi == pdm.DDI_SETPOINT_CONDENSED_WORK_STATE:
            self.work_state = pd.value & 0xFFFFFFFF
        elif pd.ddi in self.MEASURED:
            return ERR_NOT_SETTABLE
        else:
            return ERR_DDI_NOT_SUPPORTED
        self.setpoints_rx += 1
        self.last_setpoint_t = self.clock()
        self._compute_target(self.clock())
        return 0

    def _pdack(self, pd: pdm.PD, err: int) -> None:
        b0 = pdm.CMD_PDACK | ((pd.element & 0x0F) << 4)
        data = bytes((b0, (pd.element >> 4) & 0xFF)) + pd.ddi.to_bytes(2, "little")
        self._send_pd(data + bytes((err, 0xF0 | pd.command, 0xFF, 0xFF)))

    def version_response(self) -> bytes:
        """The client's version message announces what its pool offers (ISO 11783-10
        B.4 technical capabilities): implement section control, 1 boom and its sections,
        when the pool has a settable setpoint condensed work state (DDI 290) and section
        elements."""
        sc = self.ddop.find(pdm.DDI_SETPOINT_CONDENSED_WORK_STATE, settable=True)
        n = len(self.ddop.sections())
        if sc and n:
            return pdm.version_message(pdm.SERVER_OPTION_SECTION_CONTROL, 1, min(255, n))
        return pdm.version_message(0, 0, 0)

    def _on_dd(self, sub: int, d: bytes) -> None:
        if sub == pdm.DD_STRUCTURE and self.state == "wait_label":
            if bytes(d[1:8]) == bytes(self.ddop.device.structure_label):
                # same structure: the localization label decides whether the TC's copy
                # still presents our designators and units (ISO 11783-10 B.5.5)
                self._send_pd(b"\x21" + b"\xff" * 7)
                self._to("wait_localization")
            else:
                self._upload()
        elif sub == pdm.DD_LOCALIZATION and self.state == "wait_localization":
            if bytes(d[1:8]) == bytes(self.ddop.device.localization_label):
                log.info("[%s] TC already holds our pool: activating", self.node.label)
                self._activate()
            else:
                self._upload()
        elif sub == pdm.DD_REQ_TRANSFER_RESP and self.state == "wait_transfer_ok":
            if d[1] != 0:
                self.alarms.add("isobus_tc_no_memory")
                log.error(
                    "[%s] TC has no memory for our %d-byte pool", self.node.label, len(self.pool)
                )
                self._to("rejected")
                return
            self._transfer = self.node.send(
                PGN_PROCESS_DATA, b"\x61" + self.pool, self.tc_addr or 0, 5
            )
            self._to("wait_transfer_resp")
        elif sub == pdm.DD_TRANSFER_RESP and self.state == "wait_transfer_resp":
            if d[1] != 0:
                self.alarms.add("isobus_ddop_rejected")
                log.error("[%s] TC refused the pool transfer: errors 0x%02X", self.node.label, d[1])
                self._to("rejected")
                return
            self._activate()
        elif sub == pdm.DD_ACTIVATE_RESP and self.state == "wait_activate":
            if d[1] != 0:
                self.alarms.add("isobus_ddop_rejected")
                log.error(
                    "[%s] TC refused activation: errors 0x%02X, object %d, pool errors 0x%02X",
                    self.node.label,
                    d[1],
                    d[4] | d[5] << 8,
                    d[6],
                )
                self._to("rejected")
                return
            self.alarms.discard("isobus_ddop_rejected")
            log.info("[%s] pool active on TC 0x%02X", self.node.label, self.tc_addr or 0)
            self._to("connected")

    def _upload(self) -> None:
        self._send_pd(bytes((0x41,)) + len(self.pool).to_bytes(4, "little") + b"\xff\xff\xff")
        self._to("wait_transfer_ok")

    def _request_label(self) -> None:
        self._send_pd(b"\x01" + b"\xff" * 7)
        self._to("wait_label")

    def _activate(self) -> None:
        self._send_pd(b"\x81\xff" + b"\xff" * 6)
        self._to("wait_activate")

    # -- periodic ----------------------------------------------------------------

    def _compute_target(self, now: float) -> None:
        tc_alive = now - self.last_tc_status_t <= TC_TIMEOUT_S
        speed_ok = now - self.speed_t <= SPEED_TIMEOUT_S
        rate = self.rate_kg_ha()
        if not (self.connected and tc_alive and speed_ok and rate > 0 and any(self.sections())):
            self.target_rpm = 0.0
            return
        rpm = shaft_rpm_for_rate(self.cal, rate, self.width_m, self.speed_m_s)
        self.target_rpm = min(max(rpm, self.cal.min_rpm), self.cal.max_rpm)

    def update(self, actual_rpm: float | None = None) -> float:
        """Run the connection state machine, triggered measurements and the client task
        message; returns the shaft speed target (r/min) for the motor loop."""
        now = self.clock()
        if actual_rpm is not None:
            self.actual_rpm = float(actual_rpm)
        dt = max(0.0, now - self._last_update_t)
        self._last_update_t = now
        if now - self.speed_t <= SPEED_TIMEOUT_S:
            self.distance_m += self.speed_m_s * dt
        if not self.node.claimed:
            self.target_rpm = 0.0
            return 0.0
        tc_alive = now - self.last_tc_status_t <= TC_TIMEOUT_S
        if self.state != "wait_tc" and not tc_alive:
            log.error(
                "[%s] TC status lost for %.0f s: metering stops", self.node.label, TC_TIMEOUT_S
            )
            self.alarms.add("isobus_tc_lost")
            self.tc_losses += 1
            self.tc_addr = None
            self.tc_name = None
            self.triggers.clear()
            self._to("wait_tc")
        if self.state == "wait_tc" and self.tc_addr is not None and tc_alive:
            self.node.send(PGN_WORKING_SET_MASTER, b"\x01" + b"\xff" * 7, GLOBAL_ADDRESS, 7)
            self._send_task(now)
            self._send_pd(b"\x00" + b"\xff" * 7)  # request version
            self._to("wait_version")
        elif self.state.startswith("wait_") and self.state != "wait_tc":
            if now - self.state_t > STEP_TIMEOUT_S:
                log.warning("[%s] no answer in %s: starting over", self.node.label, self.state)
                self._to("wait_tc")
        if self.state != "wait_tc" and now - self._last_task_t >= CLIENT_TASK_PERIOD_S:
            self._send_task(now)
        self._compute_target(now)
        if self.connected:
            self._measurements(now)
        return self.target_rpm

    def _send_task(self, now: float) -> None:
        self._last_task_t = now
        active = 0x01 if self.connected else 0x00
        self._send_pd(bytes((0xFF, 0xFF, 0xFF, 0xFF, active, 0, 0, 0)))

    def _measurements(self, now: float) -> None:
        for ddi, tr in self.triggers.items():
            val = None
            if tr.time_ms and (now - tr.last_t) * 1000.0 >= tr.time_ms:
                val = self._value(ddi)
            if tr.distance_mm and (self.distance_m - tr.last_dist_m) * 1000.0 >= tr.distance_mm:
                val = self._value(ddi)
            if tr.change:
                v = self._value(ddi)
                if tr.last_value is None or abs(v - tr.last_value) >= tr.change:
                    val = v
            if val is not None:
                tr.last_t = now
                tr.last_dist_m = self.distance_m
                tr.last_value = val
                self._send_pd(pdm.encode(pdm.CMD_VALUE, METER_ELEMENT, ddi, val))


def run_ecu(
    ecu: RateEcu, motor: Any, stop: Any, period_s: float = 0.01, poll_s: float = 0.002
) -> None:
    """Live ECU loop: poll the bus, set the motor loop's setpoint from the ECU, report its
    actual speed. ``motor`` is a ``motor.MotorLoop`` running in its own thread."""
    nxt = time.monotonic()
    while not stop.is_set():
        ecu.node.poll(poll_s)
        if time.monotonic() >= nxt:
            motor.setpoint_rpm = ecu.update(motor.rpm)
            nxt += period_s
    motor.setpoint_rpm = 0.0
