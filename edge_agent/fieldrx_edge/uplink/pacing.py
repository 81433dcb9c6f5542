"""Upload pacing: a batch that is not full waits for the upload period (full batches go at
once), so an agent online does not pay the server a request per fix.

A request's fixed server cost (token, transaction, locks, statements: ~4-6 ms of CPU)
dwarfs a small batch's records; in real time the cadence, not the record count, sets the
server's CPU per machine-hour (``protocol.UPLOAD_PERIOD_S``, docs/scale.md section 5).
Shared by ``HttpSender`` and ``MqttSender``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable

from fieldrx_edge.protocol import UPLOAD_PERIOD_S


def upload_period(profile: str, asked: float | None = None) -> float:
    """``asked`` (a ``--upload-period``), else the uplink profile's period."""
    return UPLOAD_PERIOD_S[profile] if asked is None else asked


class UploadPacer:
    """When a sender's ``run`` loop may upload: once ``period_s`` has passed since the
    previous upload, or at once while a queue holds a full batch (a backlog). A period of
    0 uploads as soon as anything is pending."""

    def __init__(self, period_s: float, batch_size: int) -> None:
        self.period_s = period_s
        self.batch_size = batch_size
        self._last = -math.inf

    def due_in(self, backlogs: Iterable[int]) -> float:
        """Seconds until an upload of queues holding ``backlogs`` records is due (0: now)."""
        wait = self._last + self.period_s - time.monotonic()
        if wait <= 0 or any(b >= self.batch_size for b in backlogs):
            return 0.0
        return wait

    def uploaded(self) -> None:
        """An upload went (or was attempted) now."""
        self._last = time.monotonic()
