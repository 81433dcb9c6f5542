"""WebSocket /live?token=<user token>: positions, status, alerts and job progress, live.

Messages are JSON objects with "type": "status" (a snapshot of every machine
when the socket opens), "position" (a machine's latest record after each
stored batch), "alert" (started / ended) and "job" (state or progress
changes). They reach every API process through PostgreSQL LISTEN/NOTIFY
(fieldrx.fleet.live), so a browser sees telemetry posted to any process.
"""

from __future__ import annotations

import asyncio
import contextlib
import json

from fastapi import APIRouter, Query, WebSocket, WebSocketDisconnect
from starlette.concurrency import run_in_threadpool

from fieldrx.auth.deps import Principal, resolve_token
from fieldrx.db.session import get_sessionmaker
from fieldrx.fleet.live import hub
from fieldrx.fleet.status import machine_status
from fieldrx.settings import get_settings

router = APIRouter(tags=["live"])


def _auth_and_snapshot(token: str) -> tuple[Principal | None, list[dict]]:
    with get_sessionmaker()() as session:
        p = resolve_token(session, token)
        if p is None or p.is_device:
            return None, []
        return p, machine_status(session, p.organisation_id, get_settings().heartbeat_timeout_s)


@router.websocket("/live")
async def live(ws: WebSocket, token: str = Query(default="")) -> None:
    principal, snapshot = await run_in_threadpool(_auth_and_snapshot, token)
    if principal is None:
        await ws.close(code=4401, reason="invalid or missing user token (?token=)")
        return
    await ws.accept()
    org = principal.organisation_id
    q = await hub.subscribe(org)
    reader = asyncio.create_task(_drain(ws))
    try:
        await ws.send_text(json.dumps({"type": "status", "machines": snapshot}, default=str))
        while not reader.done():
            getter = asyncio.create_task(q.get())
            done, _ = await asyncio.wait({getter, reader}, return_when=asyncio.FIRST_COMPLETED)
            if getter in done:
                await ws.send_text(getter.result())
            else:
                getter.cancel()
    except (WebSocketDisconnect, RuntimeError):
        pass
    finally:
        hub.unsubscribe(org, q)
        reader.cancel()
        with contextlib.suppress(BaseException):
            await reader


async def _drain(ws: WebSocket) -> None:
    """Read (and ignore) client messages until the socket closes."""
    with contextlib.suppress(WebSocketDisconnect, RuntimeError):
        while True:
            msg = await ws.receive()
            if msg.get("type") == "websocket.disconnect":
                return
