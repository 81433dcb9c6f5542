"""POST /telemetry: a device's batch of records -> TelemetryAck (fieldrx_edge.protocol).

The body is parsed with orjson and validated per record (not through a
pydantic model, which costs several times more per record); a bad record is
rejected on its own with a reason, the rest is stored (fieldrx.fleet.ingest).
Records naming another machine than the device token's are rejected one by one.
The batch names its stream (telemetry format 2: ``{"format": 2, "stream": id,
"stream_start": n, "records": [...]}``); a batch without one (format 1) is the
machine's legacy stream. A thin-profile agent's cell records come as cell
batches (format 3, ``"kind": "cells"``) on their own stream: ``fleet.cellrecords``.
It sends both in one request (``{"format": 3, "kind": "batches", "batches": [...]}``,
``protocol.MULTI_KIND``): one token check and one request instead of two; the answer is
``{"acks": [...]}``, one ack per batch; a track and a cell batch share one transaction,
and a batch the database refuses does not take the other down (``fleet.multibatch``:
its ack carries ``error``). The OpenAPI document describes every form
(``api.schemas.telemetry.TelemetryRequestIn``) and both answers.

Authentication: ``Authorization: Bearer <device token>`` with the same rules
as every endpoint (401 unknown/revoked/expired, 403 for a person's token),
checked on the ingest connection in one statement (fieldrx.fleet.auth).

Served by a plain Starlette route that ``create_app`` puts first (``ingest_route``): the
FastAPI route below only describes the endpoint in the OpenAPI document. Profiled in a
running uvicorn worker (py-spy, thin-profile requests, docs/scale.md section 5), a third
of the worker's CPU went to the web stack: FastAPI's dependency solving for the bearer
header (an ``HTTPAuthorizationCredentials`` model per request) and matching the path
against every router mounted before this one. The fast route reads the header with the
same parsing and the same 401 (``auth.deps.bearer_token_of``).
"""

from __future__ import annotations

from fastapi import APIRouter, Depends, HTTPException, Request, status
from fastapi.responses import Response
from sqlalchemy import select
from starlette.concurrency import run_in_threadpool
from starlette.routing import Route

from fieldrx.api.common import ApiError, get_scoped
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.telemetry import (
    MAX_RECORDS,
    ProtocolRecordSchema,
    StreamOut,
    TelemetryAckOut,
    TelemetryAcksOut,
    TelemetryRequestIn,
)
from fieldrx.apidocs import schema_and_components
from fieldrx.auth.deps import SessionDep, UserDep, bearer_token, bearer_token_of
from fieldrx.db.models import Machine, TelemetryStream
from fieldrx.fleet.auth import device_of
from fieldrx.fleet.db import raw_connection
from fieldrx.fleet.ingest.model import IngestError
from fieldrx.fleet.ingest.parse import parse_request
from fieldrx.fleet.multibatch import ingest_batches, store

router = APIRouter(tags=["telemetry"], responses=ERRORS)

# the request body's schema for ``openapi_extra`` (the route reads the body itself) and the
# schemas it refers to: ``create_app`` adds them to the document (``apidocs.add_components``)
REQUEST_SCHEMA, REQUEST_COMPONENTS = schema_and_components(TelemetryRequestIn, ProtocolRecordSchema)


def _ingest(token: str, body: bytes) -> bytes:
    with raw_connection() as conn:
        who = device_of(conn, token)
        if who is None:
            raise HTTPException(
                status.HTTP_401_UNAUTHORIZED,
                "invalid, expired or revoked token",
                headers={"WWW-Authenticate": "Bearer"},
            )
        kind, machine_id = who
        if kind != "device" or machine_id is None:
            raise HTTPException(status.HTTP_403_FORBIDDEN, "a device token is required")
        try:
            parsed = parse_request(body)
        except IngestError as exc:
            raise ApiError(422, str(exc)) from exc
        batches = parsed if isinstance(parsed, list) else [parsed]
        n = sum(len(b.records) for b in batches)
        if n > MAX_RECORDS:
            raise ApiError(413, f"at most {MAX_RECORDS} records per request, got {n}")
        if isinstance(parsed, list):
            return b'{"acks":[' + b",".join(ingest_batches(conn, machine_id, batches)) + b"]}"
        return store(conn, machine_id, parsed).to_json()


@router.post(
    "/telemetry",
    summary="Store a batch of telemetry records (device token)",
    response_class=Response,
    # declares the bearer scheme in the OpenAPI document; requests are served by
    # ``ingest_route`` (matched first), which reads the header itself
    dependencies=[Depends(bearer_token)],
    openapi_extra={
        "requestBody": {
            "required": True,
            "content": {
                "application/json": {"schema": REQUEST_SCHEMA},
            },
        }
    },
    responses={
        200: {
            # documentation only: FastAPI validates no answer of a ``Response``
            "model": TelemetryAckOut | TelemetryAcksOut,
            "description": "what was stored, deduplicated and rejected (record by record): "
            'one ack, or ``{"acks": [...]}`` for several batches',
        }
    },
)
async def post_telemetry(request: Request) -> Response:
    token = bearer_token_of(request.headers.get("authorization"))
    body = await request.body()
    content = await run_in_threadpool(_ingest, token, body)
    return Response(content=content, media_type="application/json")


def ingest_route(prefix: str) -> Route:
    """POST ``{prefix}/telemetry`` as a plain Starlette route (no dependency solving, no
    request model), for ``create_app`` to put before every router; same endpoint, same
    answers as the documented route above."""
    return Route(f"{prefix}/telemetry", post_telemetry, methods=["POST"])


@router.get(
    "/machines/{machine_id:int}/telemetry-streams",
    response_model=list[StreamOut],
    summary="The machine's telemetry streams (one per agent queue), most recent first",
)
def list_streams(machine_id: int, principal: UserDep, session: SessionDep) -> list[StreamOut]:
    """A new stream appears when an agent's queue is replaced (new tablet, wiped state);
    two streams sending at the same time are two agents with one device token (the
    ``duplicate_stream`` alert). Every stream's records are kept."""
    get_scoped(session, Machine, machine_id, principal)
    rows = session.scalars(
        select(TelemetryStream)
        .where(TelemetryStream.machine_id == machine_id)
        .order_by(TelemetryStream.last_seen_at.desc())
    )
    return [
        StreamOut(
            stream=r.stream,
            first_seq=r.first_seq,
            acked_seq=r.acked_seq,
            n_records=r.n_records,
            first_seen_at=r.first_seen_at,
            last_seen_at=r.last_seen_at,
            first_t=r.first_t,
            last_t=r.last_t,
        )
        for r in rows
    ]
