"""ISO 11783 network management for one control function: address claim, TP, BAM, ETP.

A ``Node`` is one internal control function on a python-can bus. It is driven by
``poll()`` (read frames, run timers), from a thread in live use or step by step in
simulation, so every protocol below is a non-blocking state machine and a simulation
is deterministic. Complete messages (single frames and reassembled transfers) addressed
to this node or broadcast go to the ``handlers``.

Address claim (ISO 11783-5 sec. 4.4, J1939-81 sec. 4.4): the node sends Address Claimed
(PGN 0xEE00, DA global, data = its 8-byte NAME) from its preferred address and owns it
after 250 ms without a contending claim. A claim for the same address from another NAME is
contention: the numerically lower NAME wins and re-sends its claim; the loser, if
self-configurable, claims the next free address in 128..247, else sends Cannot Claim
(SA 0xFE). A node that loses an address it already owned re-claims the same way. A
Request (PGN 0xEA00) for PGN 0xEE00 is answered with the claim; a frame from another
node carrying our own source address triggers a new claim (a conflict). At start the
node first sends a Request for Address Claimed to global (from the null address, ISO
11783-5 sec. 4.4.3 / J1939-81 sec. 4.4.2.2), so every node that claimed before it answers
and ``peers`` knows their NAMEs (a TC keys stored pools by NAME).

Requests (ISO 11783-3 sec. 5.4.4, PGN 0xEA00): a role answers the PGNs it provides through
``responders``; a destination-specific request for any other PGN is answered with a
negative acknowledgement (ISO 11783-3 sec. 5.4.5, J1939-21 sec. 5.4.4: PGN 0xE800,
control byte 1 = NACK, group function 0xFF, bytes 2-3 0xFF, byte 4 the requester's
address, bytes 5-7 the PGN; sent to global), so the requester need not wait for a
time-out. Global requests for unknown PGNs get no answer (the standard forbids NACKing
them).

Transport protocol (ISO 11783-3 sec. 5.10, J1939-21 sec. 5.10), 9..1785 bytes, PGN
0xEC00 connection management, data in PGN 0xEB00 frames (byte 0 sequence 1..255, 7 data
bytes, last frame padded with 0xFF):

    RTS   0x10 | size (2) | packets | max packets per CTS | PGN (3)
    CTS   0x11 | packets that may be sent | next packet | 0xFF 0xFF | PGN (3)
    EoMA  0x13 | size (2) | packets | 0xFF | PGN (3)
    BAM   0x20 | size (2) | packets | 0xFF | PGN (3)       (to global; 50..200 ms per packet)
    Abort 0xFF | reason | 0xFF 0xFF 0xFF | PGN (3)

Extended transport protocol (ISO 11783-3 sec. 5.11), over 1785 bytes, destination
specific, PGN 0xC800 connection management, data in PGN 0xC700 frames:

    RTS   0x14 | size (4) | PGN (3)
    CTS   0x15 | packets that may be sent | next packet number (3) | PGN (3)
    DPO   0x16 | packets in this block | packet offset (3) | PGN (3)
    EoMA  0x17 | size (4) | PGN (3)
    Abort 0xFF | reason | 0xFF 0xFF 0xFF | PGN (3)

A data frame's sequence number counts from 1 after the last DPO; packet number = offset +
sequence. Abort reasons used: 1 already in a session, 3 timeout, 6 unexpected data
transfer, 7 bad sequence number, 9 size out of range (J1939-21 Table 7).

Public descriptions used: AgIsoStack++ ``can_address_claim_state_machine.cpp``,
``can_transport_protocol.cpp``, ``can_extended_transport_protocol.cpp`` (multiplexor
constants 0x14-0x17, 0xFF; DPO byte layout) and its Concepts page; the Rust ``j1939``
crate's ``transport.rs`` (TP multiplexors 0x10/0x11/0x13/0x20/0xFF, 1785-byte limit).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from fieldrx_edge.isobus.j1939 import (
    GLOBAL_ADDRESS,
    NULL_ADDRESS,
    PGN_ACKNOWLEDGE,
    PGN_ADDRESS_CLAIM,
    PGN_ETP_CM,
    PGN_ETP_DT,
    PGN_REQUEST,
    PGN_TP_CM,
    PGN_TP_DT,
    Name,
    decode_id,
    encode_id,
)

log = logging.getLogger(__name__)

TP_MAX = 1785
ETP_MAX = 117_440_505
CLAIM_WAIT_S = 0.25
T1_S = 0.75  # receiver: gap between data frames
T2_S = 1.25  # receiver: data after CTS
T3_S = 1.25  # sender: CTS / EoMA after the last data frame
BAM_GAP_S = 0.05

ABORT_BUSY = 1
ABORT_TIMEOUT = 3
ABORT_UNEXPECTED_DT = 6
ABORT_BAD_SEQUENCE = 7
ABORT_SIZE = 9


@dataclass
class Message:
    """One complete message: a single frame or a reassembled transfer."""

    pgn: int
    data: bytes
    sa: int
    da: int
    priority: int = 6
    t: float = 0.0


@dataclass
class NodeStats:
    frames_rx: int = 0
    frames_tx: int = 0
    messages_rx: int = 0
    malformed: int = 0
    tx_errors: int = 0
    rx_errors: int = 0
    aborts_rx: int = 0
    aborts_tx: int = 0
    handler_errors: int = 0
    transfers_rx: int = 0
    transfers_tx: int = 0
    address_conflicts: int = 0
    error_frames: int = 0

    def to_dict(self) -> dict[str, int]:
        return dict(self.__dict__)


def _pgn3(pgn: int) -> bytes:
    return bytes((pgn & 0xFF, (pgn >> 8) & 0xFF, (pgn >> 16) & 0xFF))


def _u24(b: bytes) -> int:
    return b[0] | b[1] << 8 | b[2] << 16


@dataclass
class _Rx:
    """A transfer being received (TP CMDT, BAM or ETP)."""

    kind: str  # "tp", "bam", "etp"
    pgn: int
    size: int
    sa: int
    da: int
    buf: bytearray
    packets: int
    window_end: int = 0  # last packet number of the current CTS window
    next_packet: int = 1  # packet number expected next
    offset: int = 0  # ETP: packet offset of the current DPO block
    last_t: float = 0.0


@dataclass
class _Tx:
    """A transfer being sent."""

    kind: str
    pgn: int
    data: bytes
    da: int
    priority: int
    packets: int
    state: str = "wait_cts"  # wait_cts, send, wait_eoma, bam, done, failed
    to_send: list[int] = field(default_factory=list)
    last_t: float = 0.0
    done: threading.Event = field(default_factory=threading.Event)
    ok: bool = False
    error: str = ""

    def finish(self, ok: bool, error: str = "") -> None:
        self.ok, self.error = ok, error
        self.state = "done" if ok else "failed"
        self.done.set()


class Node:
    """One ISO 11783 control function on a python-can bus (see module docstring)."""

    def __init__(
        self,
        bus: Any,
        name: Name,
        preferred_address: int,
        clock: Callable[[], float] = time.monotonic,
        label: str = "node",
        cts_window: int = 16,
        bam_gap_s: float = BAM_GAP_S,
    ) -> None:
        self.bus = bus
        self.name = name
        self.preferred_address = preferred_address & 0xFF
        self.clock = clock
        self.label = label
        self.cts_window = max(1, min(255, int(cts_window)))
        self.bam_gap_s = bam_gap_s
        self.address = NULL_ADDRESS
        self._claiming = NULL_ADDRESS
        self._claim_t = 0.0
        self.state = "idle"  # idle, claiming, claimed, failed
        self.peers: dict[int, Name] = {}
        self.handlers: list[Callable[[Message], None]] = []
        # PGN -> answer a request from ``sa`` (the PGNs this node provides on request)
        self.responders: dict[int, Callable[[int], None]] = {}
        self.on_address_change: list[Callable[[int, int], None]] = []
        self.stats = NodeStats()
        self.alarms: set[str] = set()
        self.bus_ok = True
        self._consecutive_tx_errors = 0
        self._rx: dict[tuple[int, int], _Rx] = {}
        self._tx: dict[tuple[int, int], _Tx] = {}  # (da, 0) -> session; BAM keyed (0xFF, 1)
        self.lock = threading.RLock()  # also taken by the roles built on this node
        self._last_warn: dict[str, float] = {}

    # -- frames ------------------------------------------------------------

    def _warn(self, key: str, msg: str, *args: Any) -> None:
        """Log at most once a second per kind: a babbling bus must not flood the log."""
        now = time.monotonic()
        if now - self._last_warn.get(key, -10.0) >= 1.0:
            self._last_warn[key] = now
            log.warning("[%s] " + msg, self.label, *args)

    def send_frame(
        self,
        pgn: int,
        data: bytes,
        da: int = GLOBAL_ADDRESS,
        priority: int = 6,
        sa: int | None = None,
    ) -> bool:
        """One CAN frame; a bus error is counted and alarmed, never raised."""
        import can

        src = self.address if sa is None else sa
        msg = can.Message(
            arbitration_id=encode_id(pgn, src, da, priority),
            data=bytes(data),
            is_extended_id=True,
        )
        try:
            self.bus.send(msg, timeout=0.05)
        except (can.CanError, OSError, ValueError) as e:
            self.stats.tx_errors += 1
            self._consecutive_tx_errors += 1
            if self._consecutive_tx_errors >= 3:
                self.bus_ok = False
                self.alarms.add("isobus_bus_off")
            self._warn("tx", "CAN send failed (%s): %s", type(e).__name__, e)
            return False
        self.stats.frames_tx += 1
        if self._consecutive_tx_errors or not self.bus_ok:  # the controller recovered
            self._consecutive_tx_errors = 0
            self.bus_ok = True
            self.alarms.discard("isobus_bus_off")
        return True

    # -- public API ----------------------------------------------------------

    def start(self) -> None:
        """Begin the address claim from the preferred address."""
        with self.lock:
            self.request(PGN_ADDRESS_CLAIM)  # from the null address: who is already here
            self._claim(self.preferred_address)

    @property
    def claimed(self) -> bool:
        return self.state == "claimed"

    @property
    def open_transfers(self) -> tuple[int, int]:
        """(being received, being sent) multi-frame transfers."""
        return len(self._rx), len(self._tx)

    def send(
        self, pgn: int, data: bytes, da: int = GLOBAL_ADDRESS, priority: int = 6
    ) -> _Tx | None:
        """Send a message of any size: one frame, TP (CMDT/BAM) or ETP.

        Returns the transfer session for multi-frame messages (``done`` is set when the
        receiver acknowledged it or it failed), None for a single frame."""
        data = bytes(data)
        with self.lock:
            if not self.claimed:
                self._warn("noaddr", "no address claimed; PGN 0x%04X not sent", pgn)
                return None
            if len(data) <= 8:
                self.send_frame(pgn, data, da, priority)
                return None
            now = self.clock()
            if len(data) <= TP_MAX:
                packets = math.ceil(len(data) / 7)
                if da == GLOBAL_ADDRESS:
                    tx = _Tx("bam", pgn, data, da, priority, packets, state="bam", last_t=now)
                    tx.to_send = list(range(1, packets + 1))
                    self._tx[(GLOBAL_ADDRESS, 1)] = tx
                    size = len(data).to_bytes(2, "little")
                    self.send_frame(PGN_TP_CM, b"\x20" + size + bytes((packets, 0xFF)) + _pgn3(pgn))
                    tx.last_t = now - self.bam_gap_s  # first packet one gap after the BAM
                    return tx
                tx = _Tx("tp", pgn, data, da, priority, packets, last_t=now)
                old = self._tx.get((da, 0))
                if old is not None and not old.done.is_set():
                    old.finish(False, "replaced")
                self._tx[(da, 0)] = tx
                size = len(data).to_bytes(2, "little")
                rts = b"\x10" + size + bytes((packets, 0xFF)) + _pgn3(pgn)
                self.send_frame(PGN_TP_CM, rts, da, 7)
                self.stats.transfers_tx += 1
                return tx
            if len(data) > ETP_MAX or da == GLOBAL_ADDRESS:
                raise ValueError("ETP is destination specific and limited to 117440505 bytes")
            packets = math.ceil(len(data) / 7)
            tx = _Tx("etp", pgn, data, da, priority, packets, last_t=now)
            old = self._tx.get((da, 0))
            if old is not None and not old.done.is_set():
                old.finish(False, "replaced")
            self._tx[(da, 0)] = tx
            self.send_frame(
                PGN_ETP_CM, b"\x14" + len(data).to_bytes(4, "little") + _pgn3(pgn), da, 7
            )
            self.stats.transfers_tx += 1
            return tx

    def request(self, pgn: int, da: int = GLOBAL_ADDRESS) -> None:
        """ISO 11783-3 request (PGN 0xEA00) for ``pgn``."""
        with self.lock:
            sa = self.address if self.claimed else NULL_ADDRESS
            self.send_frame(PGN_REQUEST, _pgn3(pgn), da, 6, sa=sa)

    def poll(self, timeout: float = 0.0, max_frames: int = 1000) -> int:
        """Handle waiting frames (blocking up to ``timeout`` for the first), run timers."""
        n = 0
        try:
            msg = self.bus.recv(timeout)
        except Exception as e:  # a bus that went away: alarm, keep the node alive
            self.stats.rx_errors += 1
            self.bus_ok = False
            self.alarms.add("isobus_bus_off")
            self._warn("rx", "CAN receive failed (%s): %s", type(e).__name__, e)
            msg = None
            if timeout:
                time.sleep(min(timeout, 0.05))
        while msg is not None:
            self.handle_frame(msg)
            n += 1
            if n >= max_frames:
                break
            try:
                msg = self.bus.recv(0.0)
            except Exception:
                msg = None
        self.update()
        return n

    def close(self) -> None:
        try:
            self.bus.shutdown()
        except Exception:  # already closed
            pass

    # -- frame handling ------------------------------------------------------

    def handle_frame(self, frame: Any) -> None:
        """One received python-can message; anything malformed is counted, never raised."""
        with self.lock:
            self.stats.frames_rx += 1
            if getattr(frame, "is_error_frame", False):
                self._on_error_frame(frame)
                return
            if not getattr(frame, "is_extended_id", False):
                return  # 11-bit traffic is not ISO 11783
            try:
                self._handle(frame)
            except Exception as e:  # noqa: BLE001 - a bad frame must never stop the node
                self.stats.malformed += 1
                self._warn(
                    "bad",
                    "bad frame 0x%08X %s: %s",
                    frame.arbitration_id,
                    bytes(frame.data).hex(),
                    e,
                )

    def _on_error_frame(self, frame: Any) -> None:
        """SocketCAN error frames (linux/can/error.h): class bit 0x40 is bus-off, 0x04
        controller problems (error passive/warning). Other interfaces report through
        python-can exceptions on send/receive, handled where they occur."""
        self.stats.error_frames += 1
        cls = frame.arbitration_id
        if cls & 0x40:
            self.bus_ok = False
            self.alarms.add("isobus_bus_off")
            self._warn("busoff", "CAN controller reports bus-off (error frame 0x%X)", cls)
        elif cls & 0x04:
            self._warn("ctrl", "CAN controller error state (error frame 0x%X)", cls)

    def _handle(self, frame: Any) -> None:
        pgn, sa, da, prio = decode_id(frame.arbitration_id)
        data = bytes(frame.data)
        now = self.clock()
        if pgn == PGN_ADDRESS_CLAIM:
            self._on_claim(sa, data)
            return
        if pgn == PGN_REQUEST:
            if len(data) < 3:
                self.stats.malformed += 1
                return
            if _u24(data) == PGN_ADDRESS_CLAIM and da in (GLOBAL_ADDRESS, self.address):
                self._send_claim()
                return
            if self.claimed and da in (GLOBAL_ADDRESS, self.address) and sa != self.address:
                self._on_request(_u24(data), sa, da)
        if self.claimed and sa == self.address:
            # someone else transmits with our source address: re-assert our claim
            self.stats.address_conflicts += 1
            self.alarms.add("isobus_address_conflict")
            self._warn("conflict", "frame from our own address 0x%02X: re-claiming", sa)
            self._send_claim()
            return
        if da != GLOBAL_ADDRESS and da != self.address:
            return
        if pgn == PGN_TP_CM:
            self._on_tp_cm(sa, da, data, now)
        elif pgn == PGN_TP_DT:
            self._on_dt("tp", sa, da, data, now)
        elif pgn == PGN_ETP_CM:
            self._on_etp_cm(sa, da, data, now)
        elif pgn == PGN_ETP_DT:
            self._on_dt("etp", sa, da, data, now)
        else:
            self._deliver(Message(pgn, data, sa, da, prio, now))

    def _on_request(self, pgn: int, sa: int, da: int) -> None:
        responder = self.responders.get(pgn)
        if responder is not None:
            responder(sa)
        elif da == self.address and sa != NULL_ADDRESS:
            self.nack(pgn, sa)

    def nack(self, pgn: int, requester: int) -> None:
        """Negative acknowledgement of ``pgn`` to ``requester`` (module docstring)."""
        data = bytes((0x01, 0xFF, 0xFF, 0xFF, requester & 0xFF)) + _pgn3(pgn)
        self.send_frame(PGN_ACKNOWLEDGE, data, GLOBAL_ADDRESS, 6)

    def _deliver(self, msg: Message) -> None:
        self.stats.messages_rx += 1
        for h in list(self.handlers):
            try:
                h(msg)
            except Exception:  # noqa: BLE001
                self.stats.handler_errors += 1
                log.exception("[%s] handler failed on PGN 0x%04X", self.label, msg.pgn)

    # -- address claim -------------------------------------------------------

    def _send_claim(self) -> None:
        if self.state == "failed":
            self.send_frame(
                PGN_ADDRESS_CLAIM, self.name.to_bytes(), GLOBAL_ADDRESS, 6, sa=NULL_ADDRESS
            )
        elif self._claiming != NULL_ADDRESS:
            self.send_frame(
                PGN_ADDRESS_CLAIM, self.name.to_bytes(), GLOBAL_ADDRESS, 6, sa=self._claiming
            )

    def _claim(self, addr: int) -> None:
        old = self.address
        self._claiming = addr
        self.address = NULL_ADDRESS
        self.state = "claiming"
        self._claim_t = self.clock()
        self._send_claim()
        if old != NULL_ADDRESS:
            for cb in self.on_address_change:
                cb(old, NULL_ADDRESS)

    def _free_address(self, after: int) -> int | None:
        taken = set(self.peers)
        for a in list(range(max(128, after + 1), 248)) + list(range(128, max(128, after + 1))):
            if a not in taken:
                return a
        return None

    def _on_claim(self, sa: int, data: bytes) -> None:
        if len(data) < 8:
            self.stats.malformed += 1
            return
        other = Name.from_bytes(data)
        if other == self.name:
            return  # our own claim echoed by an interface
        for a, n in list(self.peers.items()):
            if n == other and a != sa:
                del self.peers[a]
        if sa == NULL_ADDRESS:
            return  # cannot-claim from another node
        mine = self._claiming if self.state == "claiming" else self.address
        if sa != mine or self.state in ("idle", "failed"):
            self.peers[sa] = other
            return
        self.stats.address_conflicts += 1
        if self.name.value < other.value:
            log.info("[%s] address 0x%02X contended by a lower-priority NAME: kept", self.label, sa)
            self._send_claim()  # we win: re-assert; the other node must move
            return
        self.peers[sa] = other
        self.alarms.add("isobus_address_lost")
        if self.name.self_configurable:
            nxt = self._free_address(sa)
            if nxt is not None:
                log.warning("[%s] lost address 0x%02X, claiming 0x%02X", self.label, sa, nxt)
                self._claim(nxt)
                return
        log.error("[%s] lost address 0x%02X and cannot claim another", self.label, sa)
        old = self.address
        self.address = NULL_ADDRESS
        self._claiming = NULL_ADDRESS
        self.state = "failed"
        self._send_claim()
        for cb in self.on_address_change:
            cb(old, NULL_ADDRESS)

    # -- transport protocol ----------------------------------------------------

    def _abort(self, cm_pgn: int, da: int, reason: int, pgn: int) -> None:
        self.stats.aborts_tx += 1
        self.send_frame(cm_pgn, bytes((0xFF, reason, 0xFF, 0xFF, 0xFF)) + _pgn3(pgn), da, 7)

    def _on_tp_cm(self, sa: int, da: int, d: bytes, now: float) -> None:
        if len(d) < 8:
            self.stats.malformed += 1
            return
        mux, pgn = d[0], _u24(d[5:8])
        if mux == 0x10 and da == self.address:  # RTS
            size = d[1] | d[2] << 8
            packets = d[3]
            if not (9 <= size <= TP_MAX) or packets != math.ceil(size / 7):
                self._abort(PGN_TP_CM, sa, ABORT_SIZE, pgn)
                return
            if (sa, 0) in self._rx:
                log.info("[%s] new RTS from 0x%02X replaces an open transfer", self.label, sa)
            rx = _Rx("tp", pgn, size, sa, da, bytearray(packets * 7), packets, last_t=now)
            self._rx[(sa, 0)] = rx
            self._send_cts(rx, d[4] if d[4] else 255)
        elif mux == 0x20 and da == GLOBAL_ADDRESS:  # BAM
            size = d[1] | d[2] << 8
            packets = d[3]
            if not (9 <= size <= TP_MAX) or packets != math.ceil(size / 7):
                self.stats.malformed += 1
                return
            self._rx[(sa, 1)] = _Rx(
                "bam", pgn, size, sa, da, bytearray(packets * 7), packets, packets, 1, 0, now
            )
        elif mux == 0x11 and da == self.address:  # CTS for our transfer
            tx = self._tx.get((sa, 0))
            if tx is None or tx.kind != "tp" or tx.state in ("done", "failed"):
                self._abort(PGN_TP_CM, sa, ABORT_UNEXPECTED_DT, pgn)
                return
            n, nxt = d[1], d[2]
            tx.last_t = now
            if n == 0:
                tx.state = "wait_cts"  # hold
                return
            if not 1 <= nxt <= tx.packets:
                self._abort(PGN_TP_CM, sa, ABORT_BAD_SEQUENCE, pgn)
                tx.finish(False, "bad CTS")
                return
            tx.to_send = list(range(nxt, min(tx.packets, nxt + n - 1) + 1))
            tx.state = "send"
            self._pump_tx(tx, now)
        elif mux == 0x13 and da == self.address:  # EoMA
            tx = self._tx.pop((sa, 0), None)
            if tx is not None and tx.kind == "tp":
                tx.finish(True)
        elif mux == 0xFF:
            self.stats.aborts_rx += 1
            tx = self._tx.pop((sa, 0), None)
            if tx is not None:
                tx.finish(False, f"aborted by receiver, reason {d[1]}")
            self._rx.pop((sa, 0), None)
            self._warn("abort", "TP abort from 0x%02X reason %d PGN 0x%04X", sa, d[1], pgn)
        else:
            self.stats.malformed += 1

    def _send_cts(self, rx: _Rx, max_per_cts: int) -> None:
        remaining = rx.packets - rx.next_packet + 1
        n = min(remaining, self.cts_window, max_per_cts)
        rx.window_end = rx.next_packet + n - 1
        if rx.kind == "tp":
            cts = bytes((0x11, n, rx.next_packet, 0xFF, 0xFF)) + _pgn3(rx.pgn)
            self.send_frame(PGN_TP_CM, cts, rx.sa, 7)
        else:
            cts = bytes((0x15, n)) + rx.next_packet.to_bytes(3, "little") + _pgn3(rx.pgn)
            self.send_frame(PGN_ETP_CM, cts, rx.sa, 7)

    def _on_etp_cm(self, sa: int, da: int, d: bytes, now: float) -> None:
        if len(d) < 8:
            self.stats.malformed += 1
            return
        mux, pgn = d[0], _u24(d[5:8])
        if da != self.address:
            return
        if mux == 0x14:  # RTS
            size = int.from_bytes(d[1:5], "little")
            if not (TP_MAX < size <= ETP_MAX):
                self._abort(PGN_ETP_CM, sa, ABORT_SIZE, pgn)
                return
            packets = math.ceil(size / 7)
            new = _Rx("etp", pgn, size, sa, da, bytearray(packets * 7), packets, last_t=now)
            self._rx[(sa, 0)] = new
            self._send_cts(new, 255)
        elif mux == 0x16:  # DPO
            rx = self._rx.get((sa, 0))
            if rx is None or rx.kind != "etp":
                self._abort(PGN_ETP_CM, sa, ABORT_UNEXPECTED_DT, pgn)
                return
            rx.offset = _u24(d[2:5])
            rx.last_t = now
            if rx.offset + 1 != rx.next_packet:
                self._abort(PGN_ETP_CM, sa, ABORT_BAD_SEQUENCE, pgn)
                self._rx.pop((sa, 0), None)
        elif mux == 0x15:  # CTS
            self._on_etp_cts(sa, d, pgn, now)
        elif mux == 0x17:  # EoMA
            tx = self._tx.pop((sa, 0), None)
            if tx is not None and tx.kind == "etp":
                tx.finish(True)
        elif mux == 0xFF:
            self.stats.aborts_rx += 1
            tx = self._tx.pop((sa, 0), None)
            if tx is not None:
                tx.finish(False, f"aborted by receiver, reason {d[1]}")
            self._rx.pop((sa, 0), None)
            self._warn("abort", "ETP abort from 0x%02X reason %d PGN 0x%04X", sa, d[1], pgn)
        else:
            self.stats.malformed += 1

    def _on_etp_cts(self, sa: int, d: bytes, pgn: int, now: float) -> None:
        """An ETP clear-to-send from ``sa``: announce the window with a DPO, then send it."""
        tx = self._tx.get((sa, 0))
        if tx is None or tx.kind != "etp" or tx.state in ("done", "failed"):
            self._abort(PGN_ETP_CM, sa, ABORT_UNEXPECTED_DT, pgn)
            return
        n, nxt = d[1], _u24(d[2:5])
        tx.last_t = now
        if n == 0:
            tx.state = "wait_cts"
            return
        if not 1 <= nxt <= tx.packets:
            self._abort(PGN_ETP_CM, sa, ABORT_BAD_SEQUENCE, pgn)
            tx.finish(False, "bad CTS")
            return
        last = min(tx.packets, nxt + n - 1)
        tx.to_send = list(range(nxt, last + 1))
        dpo = bytes((0x16, len(tx.to_send))) + (nxt - 1).to_bytes(3, "little") + _pgn3(tx.pgn)
        self.send_frame(PGN_ETP_CM, dpo, sa, 7)
        tx.state = "send"
        self._pump_tx(tx, now)

    def _on_dt(self, kind: str, sa: int, da: int, d: bytes, now: float) -> None:
        if len(d) < 8:
            self.stats.malformed += 1
            return
        key = (sa, 1) if (kind == "tp" and da == GLOBAL_ADDRESS) else (sa, 0)
        rx = self._rx.get(key)
        if rx is None:
            self.stats.malformed += 1  # data without a session (late, or a stray frame)
            return
        seq = d[0]
        packet = seq if rx.kind != "etp" else rx.offset + seq
        cm = PGN_ETP_CM if rx.kind == "etp" else PGN_TP_CM
        if packet != rx.next_packet or packet > rx.window_end:
            if rx.kind == "bam":
                self._rx.pop(key, None)
                self.stats.malformed += 1
            else:
                self._abort(cm, sa, ABORT_BAD_SEQUENCE, rx.pgn)
                self._rx.pop(key, None)
            return
        i = (packet - 1) * 7
        rx.buf[i : i + 7] = d[1:8]
        rx.next_packet += 1
        rx.last_t = now
        if rx.next_packet > rx.packets:
            self._rx.pop(key, None)
            if rx.kind == "tp":
                eoma = bytes((0x13,)) + rx.size.to_bytes(2, "little") + bytes((rx.packets, 0xFF))
                self.send_frame(PGN_TP_CM, eoma + _pgn3(rx.pgn), sa, 7)
            elif rx.kind == "etp":
                eoma = b"\x17" + rx.size.to_bytes(4, "little") + _pgn3(rx.pgn)
                self.send_frame(PGN_ETP_CM, eoma, sa, 7)
            self.stats.transfers_rx += 1
            self._deliver(Message(rx.pgn, bytes(rx.buf[: rx.size]), sa, da, 6, now))
        elif rx.kind != "bam" and packet == rx.window_end:
            self._send_cts(rx, 255)

    def _pump_tx(self, tx: _Tx, now: float) -> None:
        """Send the packets of the current CTS window back to back."""
        dt_pgn = PGN_ETP_DT if tx.kind == "etp" else PGN_TP_DT
        base = tx.to_send[0] - 1 if tx.to_send else 0
        for p in tx.to_send:
            chunk = tx.data[(p - 1) * 7 : p * 7]
            chunk = chunk + b"\xff" * (7 - len(chunk))
            seq = p if tx.kind == "tp" else p - base
            if not self.send_frame(dt_pgn, bytes((seq,)) + chunk, tx.da, 7):
                tx.finish(False, "bus error")
                self._tx.pop((tx.da, 0), None)
                return
        tx.to_send = []
        tx.state = "wait_eoma"
        tx.last_t = now

    # -- timers ----------------------------------------------------------------

    def update(self) -> None:
        """Address-claim timer, BAM pacing, transfer time-outs."""
        with self.lock:
            now = self.clock()
            if self.state == "claiming" and now - self._claim_t >= CLAIM_WAIT_S:
                self.address = self._claiming
                self.state = "claimed"
                log.info("[%s] address 0x%02X claimed", self.label, self.address)
                for cb in self.on_address_change:
                    cb(NULL_ADDRESS, self.address)
            bam = self._tx.get((GLOBAL_ADDRESS, 1))
            if bam is not None and bam.to_send and now - bam.last_t >= self.bam_gap_s:
                p = bam.to_send.pop(0)
                chunk = bam.data[(p - 1) * 7 : p * 7]
                self.send_frame(PGN_TP_DT, bytes((p,)) + chunk + b"\xff" * (7 - len(chunk)))
                bam.last_t = now
                if not bam.to_send:
                    self._tx.pop((GLOBAL_ADDRESS, 1), None)
                    bam.finish(True)
            for key, tx in list(self._tx.items()):
                if tx.kind == "bam":
                    continue
                if now - tx.last_t > T3_S:  # no CTS / EoMA (J1939-21 T3; holds refresh it)
                    cm = PGN_ETP_CM if tx.kind == "etp" else PGN_TP_CM
                    self._abort(cm, tx.da, ABORT_TIMEOUT, tx.pgn)
                    self._tx.pop(key, None)
                    tx.finish(False, "timeout")
                    self._warn("tout", "transfer to 0x%02X timed out (%s)", tx.da, tx.state)
            for key, rx in list(self._rx.items()):
                if now - rx.last_t > (T2_S if rx.kind != "bam" else T1_S):
                    self._rx.pop(key, None)
                    if rx.kind != "bam":
                        cm = PGN_ETP_CM if rx.kind == "etp" else PGN_TP_CM
                        self._abort(cm, rx.sa, ABORT_TIMEOUT, rx.pgn)
                    self._warn("rtout", "transfer from 0x%02X timed out", rx.sa)

    # -- helpers for tests and the bench --------------------------------------------


def pump(nodes: list[Node], max_rounds: int = 10_000) -> int:
    """Poll nodes (non-blocking) until no frame moves: a deterministic exchange on a
    virtual bus, where a send is delivered to the other buses before it returns."""
    total = 0
    for _ in range(max_rounds):
        n = sum(node.poll(0.0) for node in nodes)
        total += n
        if n == 0:
            break
    return total
