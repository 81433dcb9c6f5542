"""One control function's frames on a python-can bus: sending a frame (a bus error is
counted and alarmed, never raised), handing complete messages to the roles, the node's
counters and rate-limited warnings.

``transfers.TransportLink`` adds multi-frame transfers on top, ``network.Node`` the
address claim and requests (the control function the roles use).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from fieldrx_edge.isobus.j1939 import GLOBAL_ADDRESS, NULL_ADDRESS, encode_id

log = logging.getLogger(__name__)


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


class Link:
    """The frame layer of one control function (see module docstring)."""

    def __init__(self, bus: Any, clock: Callable[[], float], label: str) -> None:
        self.bus = bus
        self.clock = clock
        self.label = label
        self.address = NULL_ADDRESS
        self.handlers: list[Callable[[Message], None]] = []
        self.stats = NodeStats()
        self.alarms: set[str] = set()
        self.bus_ok = True
        self._consecutive_tx_errors = 0
        self.lock = threading.RLock()  # also taken by the roles built on this node
        self._last_warn: dict[str, float] = {}

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

    def close(self) -> None:
        try:
            self.bus.shutdown()
        except Exception:  # already closed
            pass

    def _deliver(self, msg: Message) -> None:
        self.stats.messages_rx += 1
        for h in list(self.handlers):
            try:
                h(msg)
            except Exception:  # noqa: BLE001
                self.stats.handler_errors += 1
                log.exception("[%s] handler failed on PGN 0x%04X", self.label, msg.pgn)
