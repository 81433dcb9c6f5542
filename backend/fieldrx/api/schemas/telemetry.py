"""Telemetry: a device's batches (parsed record by record by ``fleet.ingest``, not through
these models: they only document the wire format) and its streams."""

from __future__ import annotations

import datetime as dt
from typing import Any

from pydantic import Field

from fieldrx.api.schemas.base import Open, Out


class TelemetryBatchIn(Open):
    """Format 2: ``{"format": 2, "stream": id, "stream_start": n, "records": [...]}``; a bare
    list of records or a batch without ``stream`` is format 1 (the machine's legacy stream).
    Each record is ``fieldrx_edge.protocol.TelemetryRecord``."""

    format: int | None = None
    stream: str | None = None
    stream_start: int | None = None
    records: list[dict[str, Any]]


class TelemetryAckOut(Open):
    """``fieldrx_edge.protocol.TelemetryAck``."""

    machine_id: int
    acked_seq: int
    stored: int = 0
    duplicates: int = 0
    rejected: list[dict[str, Any]] = Field(default_factory=list, description="{seq, reason}")


class StreamOut(Out):
    """One agent queue's numbering of a machine's telemetry (stream '' = legacy agents)."""

    stream: str
    first_seq: int
    acked_seq: int
    n_records: int
    first_seen_at: dt.datetime
    last_seen_at: dt.datetime
    first_t: dt.datetime | None
    last_t: dt.datetime | None
