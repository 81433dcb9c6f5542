"""ISO 11783 multi-frame transfers of one control function: TP, BAM and ETP.

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

Public descriptions used: AgIsoStack++ ``can_transport_protocol.cpp``,
``can_extended_transport_protocol.cpp`` (multiplexor constants 0x14-0x17, 0xFF; DPO byte
layout) and its Concepts page; the Rust ``j1939`` crate's ``transport.rs`` (TP
multiplexors 0x10/0x11/0x13/0x20/0xFF, 1785-byte limit).
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from fieldrx_edge.isobus.j1939 import (
    GLOBAL_ADDRESS,
    PGN_ETP_CM,
    PGN_ETP_DT,
    PGN_TP_CM,
    PGN_TP_DT,
    pgn3,
    u24,
)
from fieldrx_edge.isobus.link import Link, Message

log = logging.getLogger(__name__)

TP_MAX = 1785
ETP_MAX = 117_440_505
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
class OutgoingTransfer:
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


class TransportLink(Link):
    """A ``Link`` that sends and receives multi-frame transfers (see module docstring)."""

    def __init__(
        self,
        bus: Any,
        clock: Callable[[], float],
        label: str,
        cts_window: int,
        bam_gap_s: float,
    ) -> None:
        super().__init__(bus, clock, label)
        self.cts_window = max(1, min(255, int(cts_window)))
        self.bam_gap_s = bam_gap_s
        self._rx: dict[tuple[int, int], _Rx] = {}
        # (da, 0) -> session; BAM keyed (0xFF, 1)
        self._tx: dict[tuple[int, int], OutgoingTransfer] = {}

    @property
    def open_transfers(self) -> tuple[int, int]:
        """(being received, being sent) multi-frame transfers."""
        return len(self._rx), len(self._tx)

    def _start_transfer(
        self, pgn: int, data: bytes, da: int, priority: int
    ) -> OutgoingTransfer:
        """Open a multi-frame transfer of ``data`` (over 8 bytes): BAM to global, TP
        (CMDT) up to 1785 bytes, ETP beyond; the caller holds the lock."""
        now = self.clock()
        if len(data) <= TP_MAX:
            packets = math.ceil(len(data) / 7)
            if da == GLOBAL_ADDRESS:
                tx = OutgoingTransfer(
                    "bam", pgn, data, da, priority, packets, state="bam", last_t=now
                )
                tx.to_send = list(range(1, packets + 1))
                self._tx[(GLOBAL_ADDRESS, 1)] = tx
                size = len(data).to_bytes(2, "little")
                self.send_frame(PGN_TP_CM, b"\x20" + size + bytes((packets, 0xFF)) + pgn3(pgn))
                tx.last_t = now - self.bam_gap_s  # first packet one gap after the BAM
                return tx
            tx = OutgoingTransfer("tp", pgn, data, da, priority, packets, last_t=now)
            old = self._tx.get((da, 0))
            if old is not None and not old.done.is_set():
                old.finish(False, "replaced")
            self._tx[(da, 0)] = tx
            size = len(data).to_bytes(2, "little")
            rts = b"\x10" + size + bytes((packets, 0xFF)) + pgn3(pgn)
            self.send_frame(PGN_TP_CM, rts, da, 7)
            self.stats.transfers_tx += 1
            return tx
        if len(data) > ETP_MAX or da == GLOBAL_ADDRESS:
            raise ValueError("ETP is destination specific and limited to 117440505 bytes")
        packets = math.ceil(len(data) / 7)
        tx = OutgoingTransfer("etp", pgn, data, da, priority, packets, last_t=now)
        old = self._tx.get((da, 0))
        if old is not None and not old.done.is_set():
            old.finish(False, "replaced")
        self._tx[(da, 0)] = tx
        self.send_frame(
            PGN_ETP_CM, b"\x14" + len(data).to_bytes(4, "little") + pgn3(pgn), da, 7
        )
        self.stats.transfers_tx += 1
        return tx


    def _abort(self, cm_pgn: int, da: int, reason: int, pgn: int) -> None:
        self.stats.aborts_tx += 1
        self.send_frame(cm_pgn, bytes((0xFF, reason, 0xFF, 0xFF, 0xFF)) + pgn3(pgn), da, 7)

    def _on_tp_cm(self, sa: int, da: int, d: bytes, now: float) -> None:
        if len(d) < 8:
            self.stats.malformed += 1
            return
        mux, pgn = d[0], u24(d[5:8])
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
            cts = bytes((0x11, n, rx.next_packet, 0xFF, 0xFF)) + pgn3(rx.pgn)
            self.send_frame(PGN_TP_CM, cts, rx.sa, 7)
        else:
            cts = bytes((0x15, n)) + rx.next_packet.to_bytes(3, "little") + pgn3(rx.pgn)
            self.send_frame(PGN_ETP_CM, cts, rx.sa, 7)

    def _on_etp_cm(self, sa: int, da: int, d: bytes, now: float) -> None:
        if len(d) < 8:
            self.stats.malformed += 1
            return
        mux, pgn = d[0], u24(d[5:8])
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
            rx.offset = u24(d[2:5])
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
        n, nxt = d[1], u24(d[2:5])
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
        dpo = bytes((0x16, len(tx.to_send))) + (nxt - 1).to_bytes(3, "little") + pgn3(tx.pgn)
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
                self.send_frame(PGN_TP_CM, eoma + pgn3(rx.pgn), sa, 7)
            elif rx.kind == "etp":
                eoma = b"\x17" + rx.size.to_bytes(4, "little") + pgn3(rx.pgn)
                self.send_frame(PGN_ETP_CM, eoma, sa, 7)
            self.stats.transfers_rx += 1
            self._deliver(Message(rx.pgn, bytes(rx.buf[: rx.size]), sa, da, 6, now))
        elif rx.kind != "bam" and packet == rx.window_end:
            self._send_cts(rx, 255)

    def _pump_tx(self, tx: OutgoingTransfer, now: float) -> None:
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

    def _transfer_timers(self, now: float) -> None:
        """BAM pacing and transfer time-outs; the caller holds the lock."""
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
