"""WebSocket /live: positions, status, alerts and job progress, live.

The user token travels in the WebSocket subprotocol list, ``["fieldrx", <token>]``
(browsers cannot set headers on a WebSocket, and a URL ends up in access logs);
the server answers with the ``fieldrx`` subprotocol. ``?token=`` still works for
older clients and is redacted from the server's logs (fieldrx.middleware). The
token is checked again every ``FIELDRX_LIVE_TOKEN_CHECK_S`` seconds: revoking it
(or its expiry) closes the socket with code 4401.

Messages are JSON objects with "type": "status" (a snapshot of every machine
when the socket opens), "position" (a machine's latest record after each
stored batch), "alert" (started / ended) and "job" (state or progress
changes). They reach every API process through PostgreSQL LISTEN/NOTIFY
(fieldrx.fleet.live), so a browser sees telemetry posted to any process.
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime as dt
import json

from fastapi import APIRouter, Query, WebSocket, WebSocketDisconnect
from starlette.concurrency import run_in_threadpool

from fieldrx.auth.deps import Principal, resolve_token
from fieldrx.db.models import ApiToken
from fieldrx.db.session import get_sessionmaker
from fieldrx.fleet.live import hub
from fieldrx.fleet.status import machine_status
from fieldrx.settings import get_settings

router = APIRouter(tags=["live"])


SUBPROTOCOL = "fieldrx"


def _token_from(ws: WebSocket, query_token: str) -> tuple[str, str | None]:
    """(token, subprotocol to answer) from ``["fieldrx", <token>]`` or the query."""
    offered = list(ws.scope.get("subprotocols") or [])
    if SUBPROTOCOL in offered:
        rest = [p for p in offered if p != SUBPROTOCOL]
        return (rest[0] if rest else ""), SUBPROTOCOL
    return query_token, None


def _still_valid(token_id: int) -> bool:
    with get_sessionmaker()() as session:
        row = session.get(ApiToken, token_id)
        now = dt.datetime.now(dt.UTC)
        return bool(
            row is not None
            and row.revoked_at is None
            and (row.expires_at is None or row.expires_at > now)
        )


def _auth_and_snapshot(token: str) -> tuple[Principal | None, list[dict]]:
    with get_sessionmaker()() as session:
        p = resolve_token(session, token)
        if p is None or p.is_device:
            return None, []
        return p, machine_status(session, p.organisation_id, get_settings().heartbeat_timeout_s)


@router.websocket("/live")
async def live(
    ws: WebSocket,
    token: str = Query(default="", description="deprecated: use the subprotocol"),
) -> None:
    token, subprotocol = _token_from(ws, token)
    principal, snapshot = await run_in_threadpool(_auth_and_snapshot, token)
    if principal is None:
        await ws.close(code=4401, reason="invalid or missing user token")
        return
    await ws.accept(subprotocol=subprotocol)
    org = principal.organisation_id
    q = await hub.subscribe(org)
    reader = asyncio.create_task(_drain(ws))
    check_every = get_settings().live_token_check_s
    next_check = asyncio.get_running_loop().time() + check_every
    try:
        await ws.send_text(json.dumps({"type": "status", "machines": snapshot}, default=str))
        while not reader.done():
            getter = asyncio.create_task(q.get())
            left = max(0.0, next_check - asyncio.get_running_loop().time())
            done, _ = await asyncio.wait(
                {getter, reader}, timeout=left, return_when=asyncio.FIRST_COMPLETED
            )
            if getter in done:
                await ws.send_text(getter.result())
            else:
                getter.cancel()
            if asyncio.get_running_loop().time() >= next_check:
                next_check += check_every
                if not await run_in_threadpool(_still_valid, principal.token_id):
                    await ws.close(code=4401, reason="token revoked or expired")
                    break
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
