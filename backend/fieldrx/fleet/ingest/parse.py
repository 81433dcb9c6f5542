"""Ingest stage 1, parse: a request body -> one ``Batch`` or several.

Only the envelope is checked here (format, kind, stream, stream_start); the records are
the validate stage's. A body with NaN/Infinity tokens (not JSON, but what an older agent
may have queued) is still read, so only the records holding them are rejected.
"""

from __future__ import annotations

import json
from typing import Any

import orjson
from fieldrx_edge.protocol import (
    CELL_FORMAT_VERSION,
    MAX_BATCHES,
    MULTI_KIND,
    STREAM_RE,
    TELEMETRY_FORMAT_VERSION,
)

from fieldrx.fleet.ingest.model import INT8_MAX, Batch, IngestError


def _loads(body: bytes | bytearray | str) -> Any:
    try:
        return orjson.loads(body)
    except orjson.JSONDecodeError as exc:
        # NaN / Infinity tokens (Python's json.dumps writes them): read them so the
        # records holding them are rejected one by one, not the whole batch
        try:
            return json.loads(body)
        except (ValueError, RecursionError):  # nesting deeper than the interpreter's stack
            raise IngestError(f"body is not valid JSON: {exc}") from exc


def parse_batch(body: bytes | bytearray | str) -> Batch:
    """``{"records": [...], "stream": id, "stream_start": n}`` (stream optional) -> Batch;
    anything else is an ``IngestError``."""
    return _batch_of(_loads(body))


def parse_request(body: bytes | str) -> list[Batch] | Batch:
    """An HTTP body: one batch (``parse_batch``) or several in one request
    (``{"format": 3, "kind": "batches", "batches": [batch, ...]}``, protocol.MULTI_KIND: a
    thin agent's track and cell batches) -> their list."""
    obj = _loads(body)
    if not isinstance(obj, dict) or obj.get("kind") != MULTI_KIND:
        return _batch_of(obj)
    if obj.get("format") != CELL_FORMAT_VERSION:
        raise IngestError(
            f"a {MULTI_KIND!r} request must be format {CELL_FORMAT_VERSION},"
            f" got {obj.get('format')!r}"
        )
    items = obj.get("batches")
    if not isinstance(items, list) or not 1 <= len(items) <= MAX_BATCHES:
        raise IngestError(f'"batches" must be a list of 1..{MAX_BATCHES} batches')
    out = []
    for i, item in enumerate(items):
        try:
            if isinstance(item, dict) and item.get("kind") == MULTI_KIND:
                raise IngestError("batches do not nest")
            out.append(_batch_of(item))
        except IngestError as exc:
            raise IngestError(f"batches[{i}]: {exc}") from exc
    return out


def _batch_of(obj: Any) -> Batch:
    if not isinstance(obj, dict) or not isinstance(obj.get("records"), list):
        raise IngestError('body must be a JSON object {"records": [TelemetryRecord, ...]}')
    fmt = obj.get("format", 1)
    kind = obj.get("kind", "telemetry")
    if kind == "cells":  # thin profile (format 3): same stream rules, fleet.cellrecords stores
        if fmt != CELL_FORMAT_VERSION:
            raise IngestError(f"a cells batch must be format {CELL_FORMAT_VERSION}, got {fmt!r}")
    elif kind != "telemetry":
        raise IngestError(f"kind {kind!r} is not 'telemetry' or 'cells'")
    elif type(fmt) is int and fmt > TELEMETRY_FORMAT_VERSION:  # a newer agent
        raise IngestError(
            f"format {fmt!r} not supported (1..{TELEMETRY_FORMAT_VERSION}): upgrade the server"
        )
    elif type(fmt) is not int or fmt < 1:  # not a format at all: upgrading would not help
        raise IngestError(f"format must be an integer 1..{TELEMETRY_FORMAT_VERSION}, got {fmt!r}")
    stream = obj.get("stream")
    if stream is None:
        if kind == "cells":
            raise IngestError("a cells batch must name its stream")
        return Batch(obj["records"])
    if not isinstance(stream, str) or not STREAM_RE.match(stream):
        raise IngestError(f"stream must be 1-32 characters [0-9A-Za-z_-], got {stream!r}")
    start = obj.get("stream_start", 1)
    if type(start) is not int or not 1 <= start <= INT8_MAX:
        raise IngestError(f"stream_start must be a positive integer, got {start!r}")
    return Batch(obj["records"], stream, start, True, kind)
