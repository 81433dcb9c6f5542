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
``{"acks": [...]}``, one ack per batch, each batch stored in its own transaction (a
failure after the first leaves it stored: the agent resends, ingest deduplicates). The
OpenAPI description still shows the single-batch form only (issue 18: the lead
regenerates the API files).

Authentication: ``Authorization: Bearer <device token>`` with the same rules
as every endpoint (401 unknown/revoked/expired, 403 for a person's token),
checked on the ingest connection in one statement (fieldrx.fleet.auth).
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Depends, HTTPException, Request, status
from fastapi.responses import Response
from sqlalchemy import select
from starlette.concurrency import run_in_threadpool

from fieldrx.api.common import ApiError, get_scoped
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.telemetry import StreamOut, TelemetryAckOut, TelemetryBatchIn
from fieldrx.auth.deps import SessionDep, UserDep, bearer_token
from fieldrx.db.models import Machine, TelemetryStream
from fieldrx.fleet.auth import device_of
from fieldrx.fleet.cellrecords import ingest_cells
from fieldrx.fleet.db import raw_connection
from fieldrx.fleet.ingest import Batch, IngestError, IngestResult, ingest, parse_request

router = APIRouter(tags=["telemetry"], responses=ERRORS)

MAX_RECORDS = 20_000


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
        acks = [_store(conn, machine_id, b).to_json() for b in batches]
        if isinstance(parsed, list):
            return b'{"acks":[' + b",".join(acks) + b"]}"
        return acks[0]


def _store(conn: Any, machine_id: int, batch: Batch) -> IngestResult:
    if batch.kind == "cells":  # uplink profile thin: its cell records
        return ingest_cells(conn, machine_id, batch.records, batch.stream, batch.stream_start)
    return ingest(conn, machine_id, batch.records, batch.stream, batch.stream_start, batch.streamed)


@router.post(
    "/telemetry",
    summary="Store a batch of telemetry records (device token)",
    response_class=Response,
    openapi_extra={
        "requestBody": {
            "required": True,
            "content": {
                "application/json": {"schema": TelemetryBatchIn.model_json_schema()},
            },
        }
    },
    responses={
        200: {
            "description": "what was stored, deduplicated and rejected (record by record)",
            "content": {"application/json": {"schema": TelemetryAckOut.model_json_schema()}},
        }
    },
)
async def post_telemetry(
    request: Request, token: Annotated[str, Depends(bearer_token)]
) -> Response:
    body = await request.body()
    content = await run_in_threadpool(_ingest, token, body)
    return Response(content=content, media_type="application/json")


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
