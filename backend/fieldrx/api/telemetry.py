"""POST /telemetry: a device's batch of records -> TelemetryAck (fieldrx_edge.protocol).

The body is parsed with ``json`` and validated per record (not through a
pydantic model, which costs several times more per record); a bad record is
rejected on its own with a reason, the rest is stored (fieldrx.fleet.ingest).
Records naming another machine than the device token's are rejected one by one.
"""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import Response
from starlette.concurrency import run_in_threadpool

from fieldrx.api.common import ApiError
from fieldrx.auth.deps import DeviceDep
from fieldrx.fleet.db import raw_connection
from fieldrx.fleet.ingest import IngestError, IngestResult, ingest, parse_body

router = APIRouter(tags=["telemetry"])

MAX_RECORDS = 20_000


def _ingest(machine_id: int, body: bytes) -> IngestResult:
    try:
        records = parse_body(body)
    except IngestError as exc:
        raise ApiError(422, str(exc)) from exc
    if len(records) > MAX_RECORDS:
        raise ApiError(413, f"at most {MAX_RECORDS} records per request, got {len(records)}")
    with raw_connection() as conn:
        return ingest(conn, machine_id, records)


@router.post(
    "/telemetry",
    summary="Store a batch of telemetry records (device token)",
    responses={200: {"description": "TelemetryAck JSON"}},
)
async def post_telemetry(request: Request, principal: DeviceDep) -> Response:
    assert principal.machine_id is not None
    body = await request.body()
    result = await run_in_threadpool(_ingest, principal.machine_id, body)
    return Response(content=result.to_json(), media_type="application/json")
