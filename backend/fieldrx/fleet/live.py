"""Live fan-out: one PostgreSQL LISTEN connection per API process, many browsers.

Ingest (any process, HTTP or MQTT worker) queues messages with NOTIFY inside
its transaction; PostgreSQL delivers them at commit to every listening process,
and each process forwards them to its own WebSocket clients of the same
organisation. Nothing is shared in memory between processes: the only
per-process state is the list of sockets connected to that process.

While sockets are connected, each process also sweeps for machines gone silent
(``fleet.status.sweep_offline``, a few times per heartbeat timeout), so "offline"
reaches browsers even when no MQTT worker runs; the sweep announces each silence once.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
from typing import Any

import psycopg

from fieldrx.db.session import raw_dsn
from fieldrx.fleet.alerts import LIVE_CHANNEL
from fieldrx.fleet.db import raw_connection
from fieldrx.fleet.status import sweep_offline
from fieldrx.settings import get_settings

log = logging.getLogger(__name__)

QUEUE_SIZE = 1000


class LiveHub:
    """Per-process subscriber registry fed by a LISTEN task (started with the first client)."""

    def __init__(self) -> None:
        self._subs: dict[int, set[asyncio.Queue[str]]] = {}
        self._task: asyncio.Task[None] | None = None
        self._sweeper: asyncio.Task[None] | None = None
        self._ready: asyncio.Event | None = None

    async def subscribe(self, organisation_id: int) -> asyncio.Queue[str]:
        q: asyncio.Queue[str] = asyncio.Queue(QUEUE_SIZE)
        self._subs.setdefault(organisation_id, set()).add(q)
        loop = asyncio.get_running_loop()
        if self._task is None or self._task.done() or self._task.get_loop() is not loop:
            # (a new event loop, e.g. a test client's, needs its own listener)
            self._ready = asyncio.Event()
            self._task = loop.create_task(self._listen(self._ready))
        if self._sweeper is None or self._sweeper.done() or self._sweeper.get_loop() is not loop:
            self._sweeper = loop.create_task(self._sweep())
        assert self._ready is not None
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(self._ready.wait(), 5.0)
        return q

    def unsubscribe(self, organisation_id: int, q: asyncio.Queue[str]) -> None:
        subs = self._subs.get(organisation_id)
        if subs is not None:
            subs.discard(q)
            if not subs:
                del self._subs[organisation_id]

    def publish_local(self, msg: dict[str, Any]) -> None:
        org = msg.pop("org", None)
        if org is None:
            return
        text = json.dumps(msg, default=str)
        for q in list(self._subs.get(int(org), ())):
            if q.full():  # a slow browser loses its oldest messages, not the others' live view
                with contextlib.suppress(asyncio.QueueEmpty):
                    q.get_nowait()
            q.put_nowait(text)

    async def _sweep(self) -> None:
        """Offline sweep while anyone listens (period: a quarter of the timeout, 0.5-5 s)."""
        timeout = get_settings().heartbeat_timeout_s
        period = min(5.0, max(0.5, timeout / 4))
        while self._subs:
            try:
                await asyncio.to_thread(_sweep_once, timeout)
            except asyncio.CancelledError:
                raise
            except Exception as exc:  # database restart: try again next period
                log.warning("offline sweep failed: %s", exc)
            await asyncio.sleep(period)

    async def _listen(self, ready: asyncio.Event) -> None:
        while True:
            try:
                async with await psycopg.AsyncConnection.connect(
                    raw_dsn(), autocommit=True, options="-c jit=off"
                ) as conn:
                    await conn.execute(f"LISTEN {LIVE_CHANNEL}")
                    ready.set()
                    async for n in conn.notifies():
                        try:
                            msg = json.loads(n.payload)
                        except ValueError:
                            continue
                        self.publish_local(msg)
            except asyncio.CancelledError:
                raise
            except Exception as exc:  # database restart: listen again
                log.warning("live LISTEN connection lost: %s", exc)
                await asyncio.sleep(1.0)


def _sweep_once(timeout_s: float) -> None:
    with raw_connection() as conn:
        sweep_offline(conn, timeout_s)


hub = LiveHub()
