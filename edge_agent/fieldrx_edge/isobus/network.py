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

Multi-frame transfers (TP, BAM, ETP) are ``transfers.TransportLink``'s, the frame layer
``link.Link``'s; a ``Node`` is both.

Public descriptions used: AgIsoStack++ ``can_address_claim_state_machine.cpp`` and its
Concepts page.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
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
    pgn3,
    u24,
)
from fieldrx_edge.isobus.link import Message
from fieldrx_edge.isobus.transfers import BAM_GAP_S, OutgoingTransfer, TransportLink

log = logging.getLogger(__name__)

CLAIM_WAIT_S = 0.25


class Node(TransportLink):
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
        super().__init__(bus, clock, label, cts_window, bam_gap_s)
        self.name = name
        self.preferred_address = preferred_address & 0xFF
        self._claiming = NULL_ADDRESS
        self._claim_t = 0.0
        self.state = "idle"  # idle, claiming, claimed, failed
        self.peers: dict[int, Name] = {}
        # PGN -> answer a request from ``sa`` (the PGNs this node provides on request)
        self.responders: dict[int, Callable[[int], None]] = {}
        self.on_address_change: list[Callable[[int, int], None]] = []

    # -- public API ----------------------------------------------------------

    def start(self) -> None:
        """Begin the address claim from the preferred address."""
        with self.lock:
            self.request(PGN_ADDRESS_CLAIM)  # from the null address: who is already here
            self._claim(self.preferred_address)

    @property
    def claimed(self) -> bool:
        return self.state == "claimed"

    def send(
        self, pgn: int, data: bytes, da: int = GLOBAL_ADDRESS, priority: int = 6
    ) -> OutgoingTransfer | None:
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
            return self._start_transfer(pgn, data, da, priority)

    def request(self, pgn: int, da: int = GLOBAL_ADDRESS) -> None:
        """ISO 11783-3 request (PGN 0xEA00) for ``pgn``."""
        with self.lock:
            sa = self.address if self.claimed else NULL_ADDRESS
            self.send_frame(PGN_REQUEST, pgn3(pgn), da, 6, sa=sa)

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
            if u24(data) == PGN_ADDRESS_CLAIM and da in (GLOBAL_ADDRESS, self.address):
                self._send_claim()
                return
            if self.claimed and da in (GLOBAL_ADDRESS, self.address) and sa != self.address:
                self._on_request(u24(data), sa, da)
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
        data = bytes((0x01, 0xFF, 0xFF, 0xFF, requester & 0xFF)) + pgn3(pgn)
        self.send_frame(PGN_ACKNOWLEDGE, data, GLOBAL_ADDRESS, 6)

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
            self._transfer_timers(now)


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
