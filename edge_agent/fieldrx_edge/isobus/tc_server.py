"""The Task Controller server role: the agent running a FieldRx job drives any ISOBUS
implement that connects as a TC client (ISO 11783-10, TC-GEO without position-based
control, with section control).

Server side of the connection procedure (message layouts in ``process_data``): TC status
broadcast every 2 s; working set master registers a client; version request answered
(version 4, options TC-GEO + section control, 1 boom, 16 sections); structure and
localization label requests answered with the stored pool's label when this TC already
holds the client's pool (same NAME and label), else 0xFF; object-pool transfer accepted
up to ``max_pool_bytes``; the pool is parsed on arrival (``ddop.parse``) and activation
checks that it can be driven:

* a settable setpoint mass per area (DDI 6, mg/m^2) or volume per area (DDI 1,
  0.01 mm^3/m^2; needs ``density_kg_l`` to convert the job's kg/ha);
* optional: actual rate (DDI 7 / 2), actual shaft speed (DDI 390), the implement's
  ground speed (DDI 397), setpoint condensed
  work state (DDI 290) for section control, actual condensed work state (DDI 161),
  working width (DDI 67) checked against the job's.

A pool that fails is refused with activation error 0x01 (errors in the DDOP) and the
faulty object id, the alarm ``isobus_wrong_ddop`` is raised and nothing is metered.

Active, the server sends: the rate setpoint on the setpoint's element when the job's rate
changes (the runtime's locator decides per GNSS fix with the lag look-ahead, so a new
cell reaches the bus at the fix it is decided), all sections on/off by the setpoint
condensed work state (off outside the field, over applied cells, implement raised,
zero rate), both refreshed every second; the machine selected speed (PGN 0xF022,
navigation-based) from the filtered GNSS speed at every fix; and measurement commands
so the client reports the actual rate by time (200 ms) and distance (1 m) triggers when
its DDOP offers them, shaft speed by time, section state on change.

A client whose client task message stops for 6 s is dropped: alarm
``isobus_client_lost``, metering paused; it must connect again to be driven.

Public descriptions used: AgIsoStack++ ``isobus_task_controller_server.cpp`` (status,
version, label, transfer, activation, PDACK and NACK payloads; the 6 s client timeout and
2 s status period) and ``isobus_task_controller_server.hpp`` (enums, options bits,
PDACK error bits).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

from fieldrx_edge.isobus import process_data as pdm
from fieldrx_edge.isobus.ddop import (
    ELEMENT_DEVICE,
    TRIG_CHANGE,
    TRIG_DISTANCE,
    TRIG_TIME,
    Binding,
    DdopError,
    DeviceDescriptor,
    Element,
    ProcessData,
    Property,
    parse,
)
from fieldrx_edge.isobus.j1939 import (
    GLOBAL_ADDRESS,
    PGN_ACKNOWLEDGE,
    PGN_MACHINE_SELECTED_SPEED,
    PGN_PROCESS_DATA,
    PGN_WORKING_SET_MASTER,
    Name,
)
from fieldrx_edge.isobus.network import Message, Node

log = logging.getLogger(__name__)

STATUS_PERIOD_S = 2.0
CLIENT_TIMEOUT_S = 6.0
REFRESH_S = 1.0


@dataclass
class Client:
    address: int
    name: Name | None
    last_task_t: float
    version: int | None = None
    pool_size: int = 0
    pool: bytearray = field(default_factory=bytearray)
    ddop: DeviceDescriptor | None = None
    active: bool = False
    error: str = ""
    kind: str = "mass"  # or "volume"
    setpoint: Binding | None = None
    actual: Binding | None = None
    rpm: Binding | None = None
    work_state: Binding | None = None
    actual_ws: Binding | None = None
    speed: Binding | None = None
    n_sections: int = 1
    width_m: float | None = None
    measurements_sent: bool = False
    actual_rate_kg_ha: float | None = None
    actual_rpm: float | None = None
    actual_sections: list[bool] | None = None
    actual_speed_m_s: float | None = None
    values_rx: int = 0
    sent_rate: int | None = None
    sent_ws: int | None = None
    sent_t: float = -1e9


class TaskControllerServer:
    """See module docstring. ``update()`` after every ``node.poll``; ``command()`` per fix."""

    def __init__(
        self,
        node: Node,
        implement_width_m: float | None = None,
        density_kg_l: float | None = None,
        measure_time_ms: int = 200,
        measure_distance_mm: int = 1000,
        max_pool_bytes: int = 1_000_000,
    ) -> None:
        self.node = node
        self.clock = node.clock
        self.implement_width_m = implement_width_m
        self.density_kg_l = density_kg_l
        self.measure_time_ms = measure_time_ms
        self.measure_distance_mm = measure_distance_mm
        self.max_pool_bytes = max_pool_bytes
        self.clients: dict[int, Client] = {}
        self.stored: dict[tuple[int, bytes], bytes] = {}  # (NAME, structure label) -> pool
        self.alarms: set[str] = set()
        self.lost: list[int] = []
        self._status_t = -1e9
        self.distance_m = 0.0
        self._last_cmd_t: float | None = None
        self.setpoints_sent = 0
        self.values_rx = 0
        self.task_active = False  # set by the first command(): a job is running
        node.handlers.append(self._on_message)

    # -- state for the runtime ------------------------------------------------------

    @property
    def client(self) -> Client | None:
        """The active client being driven (the first one activated)."""
        for c in self.clients.values():
            if c.active:
                return c
        return None

    def alarm_list(self) -> list[str]:
        out = set(self.alarms) | set(self.node.alarms)
        if self.client is None:
            out.add("isobus_no_client")
        return sorted(out)

    # -- sending -------------------------------------------------------------------------

    def _pd(self, c: Client, data: bytes, priority: int = 5) -> None:
        self.node.send(PGN_PROCESS_DATA, data, c.address, priority)

    def _status(self) -> None:
        # byte 4 bit 0: task totals active (a job is running); no command in progress
        status = 0x01 if self.task_active else 0x00
        data = bytes((0xFE, 0xFF, 0xFF, 0xFF, status, 0xFF, 0x00, 0xFF))
        self.node.send(PGN_PROCESS_DATA, data, GLOBAL_ADDRESS, 3)

    def update(self) -> None:
        """Status broadcast, client time-outs, measurement set-up of new clients."""
        with self.node.lock:
            now = self.clock()
            if not self.node.claimed:
                return
            if now - self._status_t >= STATUS_PERIOD_S:
                self._status_t = now
                self._status()
            for addr, c in list(self.clients.items()):
                if now - c.last_task_t > CLIENT_TIMEOUT_S:
                    log.error(
                        "[%s] client 0x%02X silent for %.0f s: dropped, metering paused",
                        self.node.label,
                        addr,
                        CLIENT_TIMEOUT_S,
                    )
                    del self.clients[addr]
                    if c.active:
                        self.alarms.add("isobus_client_lost")
                        self.lost.append(addr)
                elif c.active and not c.measurements_sent:
                    self._start_measurements(c)

    def _start_measurements(self, c: Client) -> None:
        c.measurements_sent = True
        for b, time_ms, dist_mm, change in (
            (c.actual, self.measure_time_ms, self.measure_distance_mm, 0),
            (c.rpm, self.measure_time_ms, 0, 0),
            (c.actual_ws, 0, 0, 1),
            (c.speed, self.measure_time_ms, 0, 0),
        ):
            if b is None or not isinstance(b.pd, ProcessData):
                continue
            trig = b.pd.triggers
            if time_ms and trig & TRIG_TIME:
                self._pd(c, pdm.encode(pdm.CMD_MEAS_TIME, b.element_number, b.ddi, time_ms))
            if dist_mm and trig & TRIG_DISTANCE:
                self._pd(c, pdm.encode(pdm.CMD_MEAS_DISTANCE, b.element_number, b.ddi, dist_mm))
            if change and trig & TRIG_CHANGE:
                self._pd(c, pdm.encode(pdm.CMD_MEAS_CHANGE, b.element_number, b.ddi, change))
        # start from a known state: sections off, rate 0
        self._send_setpoints(c, 0, False, force=True)

    def _send_setpoints(self, c: Client, rate_raw: int, on: bool, force: bool = False) -> None:
        now = self.clock()
        refresh = force or now - c.sent_t >= REFRESH_S
        ws = None
        if c.work_state is not None:
            ws = pdm.condensed_work_state([on] * c.n_sections)
        rate_raw = rate_raw if (on or c.work_state is not None) else 0
        assert c.setpoint is not None
        # switching off: sections first; switching on: rate first
        if ws is not None and c.work_state is not None and not on and (refresh or ws != c.sent_ws):
            self._pd(
                c, pdm.encode(pdm.CMD_VALUE, c.work_state.element_number, c.work_state.ddi, ws), 3
            )
            c.sent_ws = ws
            self.setpoints_sent += 1
        if refresh or rate_raw != c.sent_rate:
            self._pd(
                c, pdm.encode(pdm.CMD_VALUE, c.setpoint.element_number, c.setpoint.ddi, rate_raw), 3
            )
            c.sent_rate = rate_raw
            self.setpoints_sent += 1
        if ws is not None and c.work_state is not None and on and (refresh or ws != c.sent_ws):
            self._pd(
                c, pdm.encode(pdm.CMD_VALUE, c.work_state.element_number, c.work_state.ddi, ws), 3
            )
            c.sent_ws = ws
            self.setpoints_sent += 1
        if refresh:
            c.sent_t = now

    def rate_raw(self, c: Client, rate_kg_ha: float) -> int:
        """The job's kg/ha in the setpoint DDI's resolution."""
        if c.kind == "mass":
            return int(round(rate_kg_ha * pdm.MG_M2_PER_KG_HA))
        assert self.density_kg_l
        return int(round(rate_kg_ha / self.density_kg_l * pdm.DDI1_BITS_PER_L_HA))

    def command(self, rate_kg_ha: float, metering: bool, speed_m_s: float | None) -> None:
        """One fix's decision: speed broadcast, rate setpoint and section state."""
        with self.node.lock:
            now = self.clock()
            if not self.task_active:
                self.task_active = True
                self._status_t = -1e9  # announce the running task at the next update
            v = max(0.0, speed_m_s or 0.0)
            if self._last_cmd_t is not None:
                self.distance_m += v * max(0.0, now - self._last_cmd_t)
            self._last_cmd_t = now
            if not self.node.claimed:
                return
            self.node.send(
                PGN_MACHINE_SELECTED_SPEED, pdm.mss_payload(v, self.distance_m), GLOBAL_ADDRESS, 3
            )
            c = self.client
            if c is None:
                return
            on = bool(metering and rate_kg_ha > 0)
            raw = self.rate_raw(c, rate_kg_ha) if on else (c.sent_rate or 0)
            if c.work_state is None and not on:
                raw = 0  # no section control: a zero rate is the only way to stop
            self._send_setpoints(c, raw, on)

    # -- receiving -----------------------------------------------------------------------

    def _nack(self, sa: int, pgn: int) -> None:
        data = bytes((0x01, 0xFF, 0xFF, 0xFF, sa)) + pgn.to_bytes(3, "little")
        self.node.send(PGN_ACKNOWLEDGE, data, sa, 6)

    def _on_message(self, msg: Message) -> None:
        now = msg.t
        if msg.pgn == PGN_WORKING_SET_MASTER:
            if msg.sa not in self.clients:
                log.info("[%s] working set master at 0x%02X", self.node.label, msg.sa)
                self.clients[msg.sa] = Client(msg.sa, self.node.peers.get(msg.sa), now)
            return
        if msg.pgn != PGN_PROCESS_DATA or msg.da != self.node.address:
            return
        c = self.clients.get(msg.sa)
        if c is None:
            self._nack(msg.sa, PGN_PROCESS_DATA)  # clients announce themselves first
            return
        d = msg.data
        if len(d) < 8:
            log.warning("[%s] short process data message from 0x%02X", self.node.label, msg.sa)
            return
        cmd, sub = d[0] & 0x0F, d[0] >> 4
        if cmd == pdm.CMD_CLIENT_TASK:
            c.last_task_t = now
        elif cmd == pdm.CMD_TECHNICAL:
            if sub == pdm.TECH_REQUEST_VERSION:
                opts = pdm.SERVER_OPTION_TCGEO_NO_PBC | pdm.SERVER_OPTION_SECTION_CONTROL
                self._pd(c, bytes((0x10, pdm.TC_VERSION, 0xFF, opts, 0x00, 1, 16, 0)))
            elif sub == pdm.TECH_VERSION:
                c.version = d[1]
        elif cmd == pdm.CMD_DEVICE_DESCRIPTOR:
            self._on_dd(c, sub, d)
        elif cmd == pdm.CMD_VALUE and c.active:
            self._on_value(c, pdm.decode(d))
        elif cmd == pdm.CMD_PDACK:
            pd = pdm.decode(d)
            if d[4]:
                self.alarms.add("isobus_pdack_error")
                log.warning(
                    "[%s] client 0x%02X refused command 0x%X for element %d DDI %d: errors 0x%02X",
                    self.node.label,
                    c.address,
                    d[5] & 0x0F,
                    pd.element,
                    pd.ddi,
                    d[4],
                )

    def _on_value(self, c: Client, pd: pdm.PD) -> None:
        c.values_rx += 1
        self.values_rx += 1
        if c.actual is not None and pd.ddi == c.actual.ddi:
            if c.kind == "mass":
                c.actual_rate_kg_ha = pd.value / pdm.MG_M2_PER_KG_HA
            elif self.density_kg_l:
                c.actual_rate_kg_ha = pd.value / pdm.DDI1_BITS_PER_L_HA * self.density_kg_l
        elif pd.ddi == pdm.DDI_ACTUAL_REVOLUTIONS:
            c.actual_rpm = pd.value / pdm.RPM_BITS
        elif pd.ddi == pdm.DDI_ACTUAL_SPEED:
            c.actual_speed_m_s = pd.value / 1000.0
        elif pd.ddi == pdm.DDI_ACTUAL_CONDENSED_WORK_STATE:
            c.actual_sections = pdm.sections_on(pd.value & 0xFFFFFFFF, c.n_sections)

    def _on_dd(self, c: Client, sub: int, d: bytes) -> None:
        if sub == pdm.DD_REQ_STRUCTURE:
            # the request may carry the client's label (AgIsoStack++ reads it) or 0xFFs;
            # either way the reply is the label of the pool stored for this NAME, if any
            nv = c.name.value if c.name else 0
            want = bytes(d[1:8])
            hit = [
                (lbl, pool)
                for (n, lbl), pool in self.stored.items()
                if n == nv and (want == b"\xff" * 7 or lbl == want)
            ]
            if hit:
                c.pool = bytearray(hit[-1][1])
                self._pd(c, b"\x11" + hit[-1][0])
            else:
                self._pd(c, b"\x11" + b"\xff" * 7)
        elif sub == pdm.DD_REQ_LOCALIZATION:
            self._pd(c, b"\x31" + b"\xff" * 7)
        elif sub == pdm.DD_REQ_TRANSFER:
            size = int.from_bytes(d[1:5], "little")
            ok = 0 < size <= self.max_pool_bytes
            c.pool_size = size if ok else 0
            c.pool = bytearray()
            self._pd(c, bytes((0x51, 0 if ok else 1)) + b"\xff" * 6)
        elif sub == pdm.DD_TRANSFER:
            part = bytes(d[1:])
            c.pool += part
            err = 0
            try:
                c.ddop = parse(bytes(c.pool), c.version or 4)
            except DdopError as e:
                c.ddop = None
                c.error = str(e)
                err = 0x02  # "any other error" in AgIsoStack++'s usage; pool unusable
                log.error(
                    "[%s] client 0x%02X pool does not parse: %s", self.node.label, c.address, e
                )
            self._pd(c, bytes((0x71, err)) + len(part).to_bytes(4, "little") + b"\xff\xff")
        elif sub == pdm.DD_ACTIVATE:
            if d[1] == 0xFF:
                err, obj = self._activate(c)
                if err:
                    self.alarms.add("isobus_wrong_ddop")
                    self._pd(
                        c, bytes((0x91, 0x01, 0xFF, 0xFF)) + obj.to_bytes(2, "little") + b"\x04\xff"
                    )
                else:
                    self._pd(c, b"\x91\x00\xff\xff\xff\xff\x00\xff")
            else:
                c.active = False
                self._pd(c, b"\x91\x00\xff\xff\xff\xff\x00\xff")
        elif sub == pdm.DD_DELETE:
            c.pool = bytearray()
            c.ddop = None
            c.active = False
            self._pd(c, b"\xb1\x00\xff" + b"\xff" * 5)

    @staticmethod
    def _width_m(dd: DeviceDescriptor, element_id: int) -> float | None:
        """Working width (DDI 67 property) of the setpoint's element or, as in most pools
        where the rate sits on a bin, of the nearest element above it (boom, device)."""
        seen: set[int] = set()
        eid = element_id
        while eid not in seen:
            seen.add(eid)
            w = _element_width(dd, eid)
            if w is not None:
                return w
            el = dd.by_id.get(eid)
            if not isinstance(el, Element) or el.element_type == ELEMENT_DEVICE:
                return None
            eid = el.parent_id
        return None

    def _activate(self, c: Client) -> tuple[int, int]:
        """Map the client's pool to the job; (error, faulty object id)."""
        if c.ddop is None and c.pool:
            try:
                c.ddop = parse(bytes(c.pool), c.version or 4)
            except DdopError as e:
                c.error = str(e)
        dd = c.ddop
        if dd is None:
            log.error(
                "[%s] client 0x%02X: no usable pool (%s)", self.node.label, c.address, c.error
            )
            return 1, 0xFFFF
        mass = dd.find(pdm.DDI_SETPOINT_MASS_PER_AREA, settable=True)
        vol = dd.find(pdm.DDI_SETPOINT_VOLUME_PER_AREA, settable=True)
        if mass:
            c.kind, c.setpoint = "mass", mass[0]
            act = dd.find(pdm.DDI_ACTUAL_MASS_PER_AREA)
        elif vol and self.density_kg_l:
            c.kind, c.setpoint = "volume", vol[0]
            act = dd.find(pdm.DDI_ACTUAL_VOLUME_PER_AREA)
        else:
            c.error = (
                "volume-rate implement (DDI 1): set the product density to convert kg/ha"
                if vol
                else "no settable setpoint mass or volume per area (DDI 6 / DDI 1)"
            )
            log.error("[%s] client 0x%02X DDOP refused: %s", self.node.label, c.address, c.error)
            return 1, dd.device.object_id
        c.actual = act[0] if act else None
        rpm = dd.find(pdm.DDI_ACTUAL_REVOLUTIONS)
        c.rpm = rpm[0] if rpm else None
        ws = dd.find(pdm.DDI_SETPOINT_CONDENSED_WORK_STATE, settable=True)
        c.work_state = ws[0] if ws else None
        aws = dd.find(pdm.DDI_ACTUAL_CONDENSED_WORK_STATE)
        c.actual_ws = aws[0] if aws else None
        spd = dd.find(pdm.DDI_ACTUAL_SPEED)  # an implement's own ground speed, if it has one
        c.speed = spd[0] if spd else None
        c.n_sections = max(1, min(16, len(dd.sections())))
        c.width_m = self._width_m(dd, c.setpoint.element_id)
        if c.width_m and self.implement_width_m:
            if abs(c.width_m - self.implement_width_m) > 0.02 * self.implement_width_m:
                self.alarms.add("isobus_width_mismatch")
                log.warning(
                    "[%s] implement reports %.2f m working width, the job plans %.2f m",
                    self.node.label,
                    c.width_m,
                    self.implement_width_m,
                )
        other = self.client
        if other is not None and other is not c:
            log.warning(
                "[%s] client 0x%02X activated while 0x%02X is driven: only one implement "
                "is driven at a time",
                self.node.label,
                c.address,
                other.address,
            )
        c.active = True
        c.measurements_sent = False
        c.sent_rate = c.sent_ws = None
        if c.name is not None:
            self.stored[(c.name.value, bytes(dd.device.structure_label))] = bytes(c.pool)
        self.alarms.discard("isobus_wrong_ddop")
        self.alarms.discard("isobus_client_lost")
        pres = c.setpoint.presentation
        log.info(
            "[%s] client 0x%02X active: %s per area on element %d (%s), %d section(s)%s",
            self.node.label,
            c.address,
            c.kind,
            c.setpoint.element_number,
            pres.unit if pres else "no presentation",
            c.n_sections,
            "" if c.work_state else ", no section control",
        )
        return 0, 0xFFFF


def _element_width(dd: DeviceDescriptor, element_id: int) -> float | None:
    for b in dd.find(pdm.DDI_ACTUAL_WORKING_WIDTH):
        if b.element_id == element_id and isinstance(b.pd, Property):
            return b.pd.value / 1000.0
    return None


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
        if self.tc.client is None and d.metering:
            d.metering = False  # nothing can meter: say so in the record
            d.target_rpm = 0.0
            d.reason = "isobus_no_client"
        d.alarms.extend(a for a in alarms if a not in d.alarms)

    def run(self, stop: Any) -> None:
        node = self.tc.node
        node.start()
        while not stop.is_set():
            node.poll(0.002)
            self.tc.update()
