"""The Task Controller server role: the agent running a FieldRx job drives any ISOBUS
implement that connects as a TC client (ISO 11783-10, TC-GEO without position-based
control, with section control).

Server side of the connection procedure (ISO 11783-10 Annex B; message layouts in
``process_data``), with no wait of the TC's own at any step: TC status broadcast every
2 s; working set master registers a client; the client's version request is answered
(version 4, options TC-GEO + section control, 1 boom, 16 sections) and the TC at once
requests the client's version (B.4: the client waits for that request before it goes on);
a request for the Language Command (PGN 0xFE0F) is answered (ISO 11783-7 sec. 8.5.2: the
TC provides it), other destination-specific requests are NACKed by the node; structure and
localization label requests are answered with the labels of the pool this TC already
holds for the client's NAME (so a reconnecting client activates without an upload), else
0xFF x 7; object-pool transfer accepted up to ``max_pool_bytes``; the pool is parsed on
arrival in the layout of the client's version (``ddop.parse``, the standard's pool rules).

Activation: a pool that breaks the rules is refused with activation error 0x01 (errors in
the DDOP), the faulty object, its parent and the pool error code (B.5.17), alarm
``isobus_wrong_ddop``. A valid pool is activated; when this TC cannot drive it (no rate
setpoint it can convert the job's unit to, see ``tc_mapping``) it says so with the alarm
``isobus_cannot_drive`` and meters nothing, rather than calling a valid pool faulty.
Mapping, all optional but the rate: actual rate (DDI 7 / 2), shaft speed (DDI 390),
ground speed (DDI 397), setpoint / actual condensed work state (DDI 290 / 161) for section
control, setpoint work state (DDI 289, the element's master switch), section control
state (DDI 160) and prescription control state (DDI 158): while the implement reports
0 (manual) the TC leaves that function to the operator (no section / rate setpoints) and
alarms ``isobus_sections_manual`` / ``isobus_rate_manual``; request default process data
(DDI 0xDFFF): requested once after activation, the client then reports its default set.
Working width (DDI 67) as a property or as process data (requested after activation) is
checked against the job's (``isobus_width_mismatch``); a pool without one is said so
(``isobus_width_unknown``).

Active, the server sends: the rate setpoint on the setpoint's element when the job's rate
changes, all sections on/off by the setpoint condensed work state (off outside the field,
over applied cells, implement raised, zero rate), both refreshed every second; the
machine selected speed (PGN 0xF022, navigation-based) at every fix; and measurement
commands so the client reports the actual rate by time (200 ms) and distance (1 m)
triggers when its DDOP offers them, shaft speed by time, section state on change.

A client whose client task message stops for 6 s is dropped: alarm
``isobus_client_lost``, metering paused; it must connect again to be driven.

Public descriptions used: AgIsoStack++ ``isobus_task_controller_server.cpp`` (status,
version, label, transfer, activation, PDACK and NACK payloads; the 6 s client timeout and
2 s status period), ``isobus_task_controller_server.hpp`` (enums, options bits, PDACK
error bits) and ``isobus_task_controller_client.cpp`` (the client's waits: 6 s for the
server's version request, then the language command request).
"""

from __future__ import annotations

import logging

from fieldrx_edge.isobus import process_data as pdm
from fieldrx_edge.isobus.ddop import (
    TRIG_CHANGE,
    TRIG_DISTANCE,
    TRIG_TIME,
    Binding,
    DdopError,
    DeviceDescriptor,
    ProcessData,
    Property,
    parse,
)
from fieldrx_edge.isobus.j1939 import (
    GLOBAL_ADDRESS,
    PGN_MACHINE_SELECTED_SPEED,
    PGN_PROCESS_DATA,
    PGN_WORKING_SET_MASTER,
)
from fieldrx_edge.isobus.link import Message
from fieldrx_edge.isobus.network import Node
from fieldrx_edge.isobus.tc_client import Client, first_binding
from fieldrx_edge.isobus.tc_mapping import RateUnits, choose_rate, from_raw, to_raw, width_binding

log = logging.getLogger(__name__)

STATUS_PERIOD_S = 2.0
CLIENT_TIMEOUT_S = 6.0
REFRESH_S = 1.0
CONTROL_STATE_MANUAL = 0
CONTROL_STATE_AUTO = 1


class TaskControllerServer:
    """See module docstring. ``update()`` after every ``node.poll``; ``command()`` per fix.
    ``units``: the job's rate unit and its product's density (from the job package)."""

    def __init__(
        self,
        node: Node,
        implement_width_m: float | None = None,
        density_kg_l: float | None = None,
        measure_time_ms: int = 200,
        measure_distance_mm: int = 1000,
        max_pool_bytes: int = 1_000_000,
        units: RateUnits | None = None,
    ) -> None:
        self.node = node
        self.clock = node.clock
        self.implement_width_m = implement_width_m
        self.units = units or RateUnits("kg/ha", density_kg_l)
        self.measure_time_ms = measure_time_ms
        self.measure_distance_mm = measure_distance_mm
        self.max_pool_bytes = max_pool_bytes
        self.clients: dict[int, Client] = {}
        # (NAME, structure label) -> the pool as received and parsed
        self.stored: dict[tuple[int, bytes], tuple[bytes, DeviceDescriptor]] = {}
        self.alarms: set[str] = set()
        self.lost: list[int] = []
        self._status_t = -1e9
        self.distance_m = 0.0
        self._last_cmd_t: float | None = None
        self.setpoints_sent = 0
        self.values_rx = 0
        self.task_active = False  # set by the first command(): a job is running
        node.handlers.append(self._on_message)
        node.responders[pdm.PGN_LANGUAGE_COMMAND] = self._send_language

    @property
    def density_kg_l(self) -> float | None:
        return self.units.density_kg_l

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

    def _send_language(self, requester: int) -> None:
        # PGN 0xFE0F is a PDU2 (broadcast) message: the answer goes to everyone
        self.node.send(pdm.PGN_LANGUAGE_COMMAND, pdm.LANGUAGE_COMMAND, GLOBAL_ADDRESS, 6)

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

    def _request_value(self, c: Client, b: Binding | None) -> None:
        if b is not None and isinstance(b.pd, ProcessData):
            self._pd(c, pdm.encode(pdm.CMD_REQUEST_VALUE, b.element_number, b.ddi, 0))

    def _start_measurements(self, c: Client) -> None:
        c.measurements_sent = True
        # the client answers with every member of its default set (ISO 11783-10 DDI 0xDFFF)
        self._request_value(c, c.default_pd)
        for b, time_ms, dist_mm, change in (
            (c.actual, self.measure_time_ms, self.measure_distance_mm, 0),
            (c.rpm, self.measure_time_ms, 0, 0),
            (c.actual_ws, 0, 0, 1),
            (c.speed, self.measure_time_ms, 0, 0),
            (c.section_state, 0, 0, 1),
            (c.rx_state, 0, 0, 1),
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
        for b in (c.width_pd, c.section_state, c.rx_state):
            self._request_value(c, b)
        # start from a known state: sections off, rate 0
        self._send_setpoints(c, 0, False, force=True)

    def _put(self, c: Client, b: Binding | None, value: int, refresh: bool) -> None:
        if b is None or (not refresh and c.sent.get(b.ddi) == value):
            return
        self._pd(c, pdm.encode(pdm.CMD_VALUE, b.element_number, b.ddi, value), 3)
        c.sent[b.ddi] = value
        self.setpoints_sent += 1

    def _send_setpoints(self, c: Client, rate_raw: int, on: bool, force: bool = False) -> None:
        """Rate, master switch (DDI 289) and sections (DDI 290); switching off, sections
        first; switching on, rate first. A function the implement reports in manual
        (DDI 160 / 158 = 0) gets no setpoints: the operator has it."""
        now = self.clock()
        refresh = force or now - c.sent_t >= REFRESH_S
        ws_b = c.work_state if c.sections_auto else None
        rate_b = c.setpoint if c.rate_auto else None
        ws = pdm.condensed_work_state([on] * c.n_sections)
        master = pdm.WS_STATE_ON if on else pdm.WS_STATE_OFF
        if c.work_state is None and not on:
            rate_raw = 0  # no section control: a zero rate is the only way to stop
        if not on:
            self._put(c, ws_b, ws, refresh)
            self._put(c, c.master, master, refresh)
        self._put(c, rate_b, rate_raw, refresh)
        if on:
            self._put(c, c.master, master, refresh)
            self._put(c, ws_b, ws, refresh)
        if refresh:
            c.sent_t = now

    def rate_raw(self, c: Client, rate: float) -> int:
        """The job's rate (in its unit) in the setpoint DDI's resolution."""
        return to_raw(c.kind, rate, self.units)

    def command(self, rate_kg_ha: float, metering: bool, speed_m_s: float | None) -> None:
        """One fix's decision: speed broadcast, rate setpoint and section state. The rate
        is in the job's unit (``units.unit``)."""
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
            if c is None or not c.drivable:
                return
            on = bool(metering and rate_kg_ha > 0)
            raw = self.rate_raw(c, rate_kg_ha) if on else (c.sent_rate or 0)
            self._send_setpoints(c, raw, on)

    # -- receiving -----------------------------------------------------------------------

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
            self.node.nack(PGN_PROCESS_DATA, msg.sa)  # clients announce themselves first
            return
        d = msg.data
        if len(d) < 8:
            log.warning("[%s] short process data message from 0x%02X", self.node.label, msg.sa)
            return
        cmd, sub = d[0] & 0x0F, d[0] >> 4
        if cmd == pdm.CMD_CLIENT_TASK:
            c.last_task_t = now
        elif cmd == pdm.CMD_TECHNICAL:
            self._on_technical(c, sub, d)
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

    def _on_technical(self, c: Client, sub: int, d: bytes) -> None:
        if sub == pdm.TECH_REQUEST_VERSION:
            opts = pdm.SERVER_OPTION_TCGEO_NO_PBC | pdm.SERVER_OPTION_SECTION_CONTROL
            self._pd(c, pdm.version_message(opts, 1, 16))
            # the client waits (6 s in AgIsoStack++) for the TC to ask its version
            self._pd(c, bytes((pdm.TECH_REQUEST_VERSION,)) + b"\xff" * 7)
        elif sub == pdm.TECH_VERSION:
            c.version = d[1]

    def _on_value(self, c: Client, pd: pdm.PD) -> None:
        c.values_rx += 1
        self.values_rx += 1
        if c.actual is not None and pd.ddi == c.actual.ddi:
            c.actual_rate_kg_ha = from_raw(c.kind, pd.value, self.units)
        elif pd.ddi == pdm.DDI_ACTUAL_REVOLUTIONS:
            c.actual_rpm = pd.value / pdm.RPM_BITS
        elif pd.ddi == pdm.DDI_ACTUAL_SPEED:
            c.actual_speed_m_s = pd.value / 1000.0
        elif pd.ddi == pdm.DDI_ACTUAL_CONDENSED_WORK_STATE:
            c.actual_sections = pdm.sections_on(pd.value & 0xFFFFFFFF, c.n_sections)
        elif pd.ddi == pdm.DDI_ACTUAL_WORKING_WIDTH and c.width_pd is not None:
            if pd.element == c.width_pd.element_number:
                c.width_m = pd.value / 1000.0
                self._check_width(c)
        elif pd.ddi == pdm.DDI_SECTION_CONTROL_STATE:
            auto = self._control_state(c, pd.value, "isobus_sections_manual")
            if auto and not c.sections_auto:
                c.sent.clear()  # back in auto: resend everything at the next fix
            c.sections_auto = auto
        elif pd.ddi == pdm.DDI_PRESCRIPTION_CONTROL_STATE:
            auto = self._control_state(c, pd.value, "isobus_rate_manual")
            if auto and not c.rate_auto:
                c.sent.clear()
            c.rate_auto = auto

    def _control_state(self, c: Client, value: int, alarm: str) -> bool:
        """DDI 160 / 158: 1 auto (the TC drives it), 0 manual or 2 error (the operator
        has it: alarm), 3 not available (no such switch: the TC drives it)."""
        auto = value not in (CONTROL_STATE_MANUAL, pdm.WS_STATE_ERROR)
        if auto:
            self.alarms.discard(alarm)
        elif alarm not in self.alarms:
            self.alarms.add(alarm)
            log.warning(
                "[%s] client 0x%02X reports %s = %d (manual): no setpoints for it",
                self.node.label,
                c.address,
                alarm.removeprefix("isobus_"),
                value,
            )
        return auto

    def _held_pool(self, c: Client, want: bytes) -> tuple[bytes, bytes, DeviceDescriptor] | None:
        """The pool stored for the client's NAME: with label ``want``, or any (0xFF x 7)."""
        nv = c.name.value if c.name else 0
        hit = [
            (lbl, raw, dd)
            for (n, lbl), (raw, dd) in self.stored.items()
            if n == nv and (want == b"\xff" * 7 or lbl == want)
        ]
        return hit[-1] if hit else None

    def _on_dd(self, c: Client, sub: int, d: bytes) -> None:
        if sub == pdm.DD_REQ_STRUCTURE:
            # the request may carry the client's label (AgIsoStack++ reads it) or 0xFFs;
            # either way the reply is the label of the pool stored for this NAME, if any
            held = self._held_pool(c, bytes(d[1:8]))
            c.held = held[2] if held else None
            if held:
                c.pool = bytearray(held[1])
                c.ddop = held[2]
            self._pd(c, b"\x11" + (held[0] if held else b"\xff" * 7))
        elif sub == pdm.DD_REQ_LOCALIZATION:
            # B.5.5: the localization label of the pool held for the client (so a client
            # whose language did not change activates it as it is)
            lbl = c.held.device.localization_label if c.held else b"\xff" * 7
            self._pd(c, b"\x31" + bytes(lbl))
        elif sub == pdm.DD_REQ_TRANSFER:
            size = int.from_bytes(d[1:5], "little")
            ok = 0 < size <= self.max_pool_bytes
            c.pool_size = size if ok else 0
            c.pool = bytearray()
            c.held = None
            self._pd(c, bytes((0x51, 0 if ok else 1)) + b"\xff" * 6)
        elif sub == pdm.DD_TRANSFER:
            self._on_transfer(c, bytes(d[1:]))
        elif sub == pdm.DD_ACTIVATE:
            self._on_activate(c, d[1] == 0xFF)
        elif sub == pdm.DD_DELETE:
            c.pool = bytearray()
            c.ddop = None
            c.held = None
            c.active = False
            self._pd(c, b"\xb1\x00\xff" + b"\xff" * 5)

    def _on_transfer(self, c: Client, part: bytes) -> None:
        c.pool += part
        err = 0
        try:
            c.ddop = parse(bytes(c.pool), c.version or pdm.TC_VERSION)
        except DdopError as e:
            c.ddop = None
            c.error = str(e)
            err = 0x02  # "any other error" in AgIsoStack++'s usage; pool unusable
            log.error("[%s] client 0x%02X pool does not parse: %s", self.node.label, c.address, e)
        self._pd(c, bytes((0x71, err)) + len(part).to_bytes(4, "little") + b"\xff\xff")

    def _on_activate(self, c: Client, activate: bool) -> None:
        if not activate:
            c.active = False
            self._pd(c, b"\x91\x00\xff\xff\xff\xff\x00\xff")
            return
        e = self._activate(c)
        if e is None:
            self._pd(c, b"\x91\x00\xff\xff\xff\xff\x00\xff")
            return
        self.alarms.add("isobus_wrong_ddop")
        self._pd(
            c,
            bytes((0x91, pdm.ACTIVATION_DDOP_ERRORS))
            + e.parent_id.to_bytes(2, "little")
            + e.object_id.to_bytes(2, "little")
            + bytes((e.code, 0xFF)),
        )

    def _activate(self, c: Client) -> DdopError | None:
        """Map the client's pool to the job; the pool's error when it breaks the rules."""
        if c.ddop is None and c.pool:
            try:
                c.ddop = parse(bytes(c.pool), c.version or pdm.TC_VERSION)
            except DdopError as e:
                c.error = str(e)
                log.error("[%s] client 0x%02X pool refused: %s", self.node.label, c.address, e)
                return e
        dd = c.ddop
        if dd is None:
            c.error = c.error or "no pool transferred"
            log.error(
                "[%s] client 0x%02X: no usable pool (%s)", self.node.label, c.address, c.error
            )
            return DdopError(c.error)
        self._map(c, dd)
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
        c.sent.clear()
        if c.name is not None:
            self.stored[(c.name.value, bytes(dd.device.structure_label))] = (bytes(c.pool), dd)
        self.alarms.discard("isobus_wrong_ddop")
        self.alarms.discard("isobus_client_lost")
        pres = c.setpoint.presentation if c.setpoint else None
        log.info(
            "[%s] client 0x%02X active: %s per area on element %s (%s), %d section(s)%s",
            self.node.label,
            c.address,
            c.kind,
            c.setpoint.element_number if c.setpoint else "-",
            pres.unit if pres else "no presentation",
            c.n_sections,
            "" if c.work_state else ", no section control",
        )
        return None

    def _map(self, c: Client, dd: DeviceDescriptor) -> None:
        rm = choose_rate(dd, self.units)
        c.kind, c.setpoint, c.actual, c.error = rm.kind, rm.setpoint, rm.actual, rm.error
        if c.setpoint is None:
            self.alarms.add("isobus_cannot_drive")
            log.error(
                "[%s] client 0x%02X activated but cannot be driven: %s; nothing is metered",
                self.node.label,
                c.address,
                c.error,
            )
        else:
            self.alarms.discard("isobus_cannot_drive")
        c.rpm = first_binding(dd.find(pdm.DDI_ACTUAL_REVOLUTIONS))
        c.work_state = first_binding(dd.find(pdm.DDI_SETPOINT_CONDENSED_WORK_STATE, settable=True))
        c.actual_ws = first_binding(dd.find(pdm.DDI_ACTUAL_CONDENSED_WORK_STATE))
        c.master = first_binding(dd.find(pdm.DDI_SETPOINT_WORK_STATE, settable=True))
        c.section_state = first_binding(dd.find(pdm.DDI_SECTION_CONTROL_STATE))
        c.rx_state = first_binding(dd.find(pdm.DDI_PRESCRIPTION_CONTROL_STATE))
        c.default_pd = first_binding(dd.find(pdm.DDI_REQUEST_DEFAULT_PD))
        c.speed = first_binding(dd.find(pdm.DDI_ACTUAL_SPEED))  # an implement's own ground speed
        c.n_sections = max(1, min(16, len(dd.sections())))
        c.sections_auto = c.rate_auto = True
        anchor = c.setpoint or c.work_state
        wb = width_binding(dd, anchor.element_id) if anchor else None
        c.width_m, c.width_pd = None, None
        if wb is not None and isinstance(wb.pd, Property):
            c.width_m = wb.pd.value / 1000.0
            self._check_width(c)
        elif wb is not None:
            c.width_pd = wb  # process data: asked for with the measurements
        else:
            self.alarms.add("isobus_width_unknown")
            log.warning(
                "[%s] client 0x%02X states no working width (DDI 67): the job's %s m is "
                "not checked against the implement",
                self.node.label,
                c.address,
                self.implement_width_m,
            )

    def _check_width(self, c: Client) -> None:
        if c.width_m is None or c.width_m <= 0:
            # a width of 0 (some clients answer 0 for a value they do not track) is no width
            self.alarms.add("isobus_width_unknown")
            log.warning(
                "[%s] client 0x%02X reports a working width of %s m: not checked",
                self.node.label,
                c.address,
                c.width_m,
            )
            return
        self.alarms.discard("isobus_width_unknown")
        if not self.implement_width_m:
            return
        if abs(c.width_m - self.implement_width_m) > 0.02 * self.implement_width_m:
            self.alarms.add("isobus_width_mismatch")
            log.warning(
                "[%s] implement reports %.2f m working width, the job plans %.2f m",
                self.node.label,
                c.width_m,
                self.implement_width_m,
            )
        else:
            self.alarms.discard("isobus_width_mismatch")
