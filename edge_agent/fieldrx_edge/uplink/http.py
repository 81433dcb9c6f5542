"""HTTP batch sender: POST /api/v1/telemetry with the device token, trim on ack.

Batches are telemetry format 2 (``TelemetryQueue.pending_batch``: stream,
stream_start, records). The ack names the stream; rejected records are logged
with the server's reasons and counted in the queue (the server acknowledges
past them, so they never block what follows). A ``stream_conflict`` ack moves
the unacknowledged records to a new stream.

Uplink profile ``thin`` has two queues (the 1 Hz track and the cell records,
``fieldrx_edge.uplink.thin``), each on its own stream: ``extra_queues`` are
sent with the main one, each trimmed by its own acks. When more than one queue has
records pending, their batches go in one request (``protocol.MULTI_KIND``): the
server checks the token once and answers one ack per batch (the thin
profile's server cost per machine-hour).
"""

from __future__ import annotations

import logging
import threading
from typing import Any

import httpx

from fieldrx_edge.protocol import CELL_FORMAT_VERSION, MULTI_KIND, TelemetryAck
from fieldrx_edge.uplink.backoff import Backoff
from fieldrx_edge.uplink.pacing import UploadPacer
from fieldrx_edge.uplink.queue import TelemetryQueue

log = logging.getLogger(__name__)


class HttpSender:
    """Sends the queue's oldest records in batches; the server's ack decides what is trimmed."""

    def __init__(
        self,
        queue: TelemetryQueue,
        base_url: str,
        token: str,
        batch_size: int = 500,
        timeout_s: float = 10.0,
        backoff: Backoff | None = None,
        extra_queues: tuple[TelemetryQueue, ...] = (),
        upload_period_s: float = 0.0,
    ) -> None:
        """``upload_period_s``: in ``run``, a batch that is not full waits this long after
        the previous upload (``pacing.UploadPacer``; 0: sent as soon as pending)."""
        self.queue = queue
        self.pacer = UploadPacer(upload_period_s, batch_size)
        self.queues = (queue, *extra_queues)
        self.url = base_url.rstrip("/") + "/api/v1/telemetry"
        self.batch_size = batch_size
        self.backoff = backoff or Backoff()
        self._client = httpx.Client(timeout=timeout_s, headers={"Authorization": f"Bearer {token}"})
        self.sent_batches = 0
        self.failures = 0
        self.last_error: str | None = None
        self.online: bool | None = None  # the last upload's outcome (None: none tried yet)

    def close(self) -> None:
        self._client.close()

    def send_once(self) -> int | None:
        """One batch per queue. Returns records trimmed, 0 if nothing pending, None on failure."""
        pending = []
        for q in self.queues:
            body, n, _ = q.pending_batch(self.batch_size)
            if n:
                pending.append((q, body))
        if len(pending) == 1:
            return self._send(*pending[0])
        if not pending:
            return 0
        body = (
            f'{{"format":{CELL_FORMAT_VERSION},"kind":"{MULTI_KIND}","batches":['.encode()
            + b",".join(b for _, b in pending)
            + b"]}"
        )
        try:
            acks = self._post(body)["acks"]
            if not isinstance(acks, list) or len(acks) != len(pending):
                raise ValueError(f"{len(pending)} batches sent, acks: {str(acks)[:200]}")
            parsed = [TelemetryAck.from_dict(a) for a in acks]
            for a in acks:  # a batch the server could not store: acked_seq 0, resent later
                if a.get("error"):
                    log.warning("server did not store a batch: %s", a["error"])
        except (httpx.HTTPError, ValueError, TypeError, AttributeError, KeyError) as exc:
            self._failed(exc)
            return None
        self.sent_batches += 1
        self.online = True
        return sum(self._apply(q, ack) for (q, _), ack in zip(pending, parsed, strict=True))

    def backlog(self) -> int:
        return sum(q.backlog() for q in self.queues)

    def _post(self, body: bytes) -> Any:
        resp = self._client.post(
            self.url, content=body, headers={"Content-Type": "application/json"}
        )
        if resp.status_code >= 400:
            raise httpx.HTTPStatusError(
                f"HTTP {resp.status_code}: {resp.text[:200]}",
                request=resp.request,
                response=resp,
            )
        return resp.json()

    def state(self) -> str:
        """connecting (nothing tried yet), online (the last upload was acked), unreachable."""
        return {None: "connecting", True: "online", False: "unreachable"}[self.online]

    def _failed(self, exc: Exception) -> None:
        self.online = False
        self.failures += 1
        self.last_error = str(exc)
        log.info("telemetry upload failed: %s", exc)

    def _send(self, queue: TelemetryQueue, body: bytes) -> int | None:
        try:
            ack = TelemetryAck.from_dict(self._post(body))
        except (httpx.HTTPError, ValueError, TypeError, AttributeError) as exc:
            self._failed(exc)
            return None
        self.sent_batches += 1
        self.online = True
        return self._apply(queue, ack)

    def _apply(self, queue: TelemetryQueue, ack: TelemetryAck) -> int:
        if ack.rejected:
            log.warning("server rejected %d records: %s", len(ack.rejected), ack.rejected[:3])
        trimmed = queue.ack(ack.acked_seq, rejected=ack.rejected, stream=ack.stream or None)
        if ack.stream_conflict:
            queue.new_stream()
        return trimmed

    def run(self, stop: threading.Event, idle_s: float = 0.2) -> None:
        """Drain forever until ``stop``, a batch that is not full at most once per upload
        period; exponential backoff while the server is unreachable."""
        while not stop.is_set():
            backlogs = [q.backlog() for q in self.queues]
            wait = self.pacer.due_in(backlogs) if any(backlogs) else idle_s
            if wait > 0:
                stop.wait(min(wait, idle_s))
                continue
            self.pacer.uploaded()
            n = self.send_once()
            if n is None:
                stop.wait(self.backoff.next_delay())
                continue
            self.backoff.reset()
            if n == 0 or self.backlog() == 0:
                stop.wait(idle_s)

    def drain(self, timeout_s: float = 30.0) -> bool:
        """Send until the queue is empty or ``timeout_s`` passes (end of a simulation)."""
        import time

        deadline = time.monotonic() + timeout_s
        while self.backlog() > 0 and time.monotonic() < deadline:
            if self.send_once() is None:
                time.sleep(min(self.backoff.next_delay(), max(0.0, deadline - time.monotonic())))
            else:
                self.backoff.reset()
        return self.backlog() == 0
