"""Telemetry: a device's batches (parsed record by record by ``fleet.ingest``, not through
these models: they only document the wire format) and its streams.

The request models follow ``fleet.ingest.parse.parse_request`` / ``_batch_of`` (the rules the
server enforces: formats, kinds, the stream pattern, ``stream_start``'s range, 1..
``MAX_BATCHES`` batches); the records are the protocol's own dataclasses
(``fieldrx_edge.protocol.TelemetryRecord`` / ``cell_records.CellRecord``), whose schemas pydantic
derives from their fields, so a field added to the protocol reaches the document without
a copy here to update. Unknown batch keys are ignored by the parser (``Open``); unknown
record fields get the record rejected (``ProtocolRecordSchema``).
"""

from __future__ import annotations

import datetime as dt
from typing import Annotated, Any, Literal

from fieldrx_edge.cell_records import CellRecord
from fieldrx_edge.protocol import (
    CELL_FORMAT_VERSION,
    MAX_BATCHES,
    MULTI_KIND,
    STREAM_RE,
    TELEMETRY_FORMAT_VERSION,
    TelemetryRecord,
)
from pydantic import Field
from pydantic.json_schema import GenerateJsonSchema, JsonSchemaValue, SkipJsonSchema
from pydantic_core import core_schema

from fieldrx.api.schemas.base import Open, Out
from fieldrx.fleet.ingest.model import INT8_MAX

MAX_RECORDS = 20_000  # per request, all batches together: more is a 413

# the literals below are the protocol's constants (a Literal cannot name a variable)
assert (CELL_FORMAT_VERSION, MULTI_KIND) == (3, "batches")

_STREAM = (
    "the id of the agent queue that numbered the records (``protocol.new_stream_id``); "
    "records are deduplicated and acknowledged per (machine, stream, seq)"
)
_STREAM_START = "the stream's first seq: its acknowledgement starts just below it when new"


class TelemetryBatchIn(Open):
    """A batch of telemetry records (``protocol.telemetry_batch_json``). Format 2 names its
    stream; a batch without ``stream`` (format 1: ``{"records": [...]}``) belongs to the
    machine's legacy stream '' and its ``stream_start`` is not read. Each record is
    checked on its own: a bad one is rejected in the ack, the others are stored."""

    format: int = Field(1, ge=1, le=TELEMETRY_FORMAT_VERSION, description="telemetry format")
    kind: Literal["telemetry"] = "telemetry"
    stream: str | None = Field(None, pattern=STREAM_RE.pattern, description=_STREAM)
    stream_start: int = Field(1, ge=1, le=INT8_MAX, description=_STREAM_START)
    records: list[TelemetryRecord] = Field(max_length=MAX_RECORDS)


class CellBatchIn(Open):
    """A batch of cell records (uplink profile ``thin``, ``protocol.cell_batch_json``): one
    record per cell the tractor left, on its own stream, deduplicated and acknowledged as
    telemetry records are."""

    format: Literal[3] = Field(description="``protocol.CELL_FORMAT_VERSION``")
    kind: Literal["cells"]
    stream: str = Field(pattern=STREAM_RE.pattern, description=_STREAM)
    stream_start: int = Field(1, ge=1, le=INT8_MAX, description=_STREAM_START)
    records: list[CellRecord] = Field(max_length=MAX_RECORDS)


class TelemetryBatchesIn(Open):
    """Several batches in one request (``protocol.MULTI_KIND``: a thin agent's track and
    cell batches with one token check); the answer is ``{"acks": [...]}``, one per batch.
    A batch whose own fields break these rules refuses the whole request (422 naming
    ``batches[i]``); its records are checked one by one, as in a batch sent alone."""

    format: Literal[3] = Field(description="``protocol.CELL_FORMAT_VERSION``")
    kind: Literal["batches"]
    batches: list[TelemetryBatchIn | CellBatchIn] = Field(min_length=1, max_length=MAX_BATCHES)


TelemetryRequestIn = Annotated[
    TelemetryBatchIn | CellBatchIn | TelemetryBatchesIn,
    Field(
        description=f'one batch, or several (``"kind": "{MULTI_KIND}"``); at most '
        f"{MAX_RECORDS} records in all (413)"
    ),
]
"""The body of ``POST /telemetry`` (``fleet.ingest.parse.parse_request``)."""


class ProtocolRecordSchema(GenerateJsonSchema):
    """Closes the protocol dataclasses' schemas (``additionalProperties: false``): their
    ``from_dict`` rejects a record with a field it does not know, whereas pydantic would
    give a dataclass nested in an ``Open`` model that model's ``extra="allow"``."""

    def dataclass_schema(self, schema: core_schema.DataclassSchema) -> JsonSchemaValue:
        out = super().dataclass_schema(schema)
        out["additionalProperties"] = False
        return out


def _no_default(schema: dict[str, Any]) -> None:
    """An optional field that is absent, never null: no ``"default": null`` next to its
    string type."""
    schema.pop("default", None)


class RejectedOut(Out):
    """A record that was not stored, and why."""

    seq: int | None = Field(description="the record's seq; null when it has no usable one")
    reason: str


class TelemetryAckOut(Out):
    """``fieldrx_edge.protocol.TelemetryAck``: everything up to ``acked_seq`` of ``stream`` is
    stored (or rejected for good). ``stream`` and ``stream_conflict`` are sent only when the
    batch named its stream, and in error acks (a format 1 agent reads its ack strictly)."""

    machine_id: int
    acked_seq: int
    stored: int
    duplicates: int
    rejected: list[RejectedOut]
    stream: str = Field("", description="the batch's stream ('': the legacy stream)")
    stream_conflict: bool = Field(
        False,
        description="the stream's numbering went backwards (seqs already stored with other "
        "records): nothing from there on was stored; the agent moves to a new stream",
    )
    error: str | SkipJsonSchema[None] = Field(
        None,
        description="only in a multi-batch answer: the batch could not be stored (acked_seq "
        "0, nothing rejected: the agent resends it); which batch and why",
        json_schema_extra=_no_default,
    )
    flagged: list[RejectedOut] = Field(
        [],
        description="records stored with a warning, and why (e.g. dated more than 400 days "
        "ago: kept in the default partition; the machine gets a far_past_records alert)",
    )


class TelemetryAcksOut(Out):
    """The answer to several batches in one request."""

    acks: list[TelemetryAckOut] = Field(
        min_length=1, max_length=MAX_BATCHES, description="one per batch, in the request's order"
    )


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
