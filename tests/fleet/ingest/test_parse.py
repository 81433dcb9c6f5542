"""The parse stage: a request body -> batches; only the envelope is checked here."""

from __future__ import annotations

import json

import pytest
from fieldrx.fleet.ingest.model import INT8_MAX, IngestError
from fieldrx.fleet.ingest.parse import parse_batch, parse_request
from fieldrx_edge.protocol import CELL_FORMAT_VERSION, MAX_BATCHES, MULTI_KIND


def test_a_format_1_batch_is_the_legacy_stream() -> None:
    b = parse_batch(b'{"records": [{"seq": 1}]}')
    assert (b.records, b.stream, b.stream_start, b.streamed, b.kind) == (
        [{"seq": 1}],
        "",
        1,
        False,
        "telemetry",
    )


def test_a_format_2_batch_names_its_stream() -> None:
    b = parse_batch(json.dumps({"format": 2, "stream": "q-1", "stream_start": 41, "records": []}))
    assert (b.stream, b.stream_start, b.streamed) == ("q-1", 41, True)


def test_nan_tokens_are_read_so_only_their_records_fail() -> None:
    b = parse_batch('{"records": [{"hdop": NaN}, {"hdop": 1.0}]}')
    assert len(b.records) == 2 and b.records[0]["hdop"] != b.records[0]["hdop"]


@pytest.mark.parametrize(
    ("body", "says"),
    [
        ("{", "not valid JSON"),
        ("[]", "must be a JSON object"),
        ('{"records": {}}', "must be a JSON object"),
        ('{"kind": "track", "records": []}', "is not 'telemetry' or 'cells'"),
        ('{"stream": "a b", "records": []}', "stream must be"),
        ('{"stream": "a", "stream_start": 0, "records": []}', "stream_start"),
        (json.dumps({"stream": "a", "stream_start": INT8_MAX + 1, "records": []}), "stream_start"),
        ('{"format": 3, "kind": "cells", "records": []}', "must name its stream"),
        ('{"format": 2, "kind": "cells", "stream": "c", "records": []}', "must be format 3"),
    ],
)
def test_a_bad_envelope_is_refused_whole(body: str, says: str) -> None:
    with pytest.raises(IngestError, match=says):
        parse_batch(body)


def _multi(batches: object, fmt: int = CELL_FORMAT_VERSION) -> str:
    return json.dumps({"format": fmt, "kind": MULTI_KIND, "batches": batches})


def test_a_request_of_several_batches_parses_each() -> None:
    cells = {"format": 3, "kind": "cells", "stream": "c", "stream_start": 1, "records": []}
    out = parse_request(_multi([{"format": 2, "stream": "t", "records": []}, cells]))
    assert isinstance(out, list) and [b.kind for b in out] == ["telemetry", "cells"]
    single = parse_request(b'{"records": []}')
    assert not isinstance(single, list) and single.records == []


@pytest.mark.parametrize(
    ("body", "says"),
    [
        (_multi([], fmt=2), "must be format 3"),
        (_multi([]), "1..8 batches"),
        (_multi([{"records": []}] * (MAX_BATCHES + 1)), "1..8 batches"),
        (_multi([{"records": []}, {"kind": MULTI_KIND, "batches": []}]), r"batches\[1\]: .*nest"),
        (_multi([{"records": []}, {"stream": "?"}]), r"batches\[1\]: "),
    ],
)
def test_a_bad_request_of_batches_names_the_batch(body: str, says: str) -> None:
    with pytest.raises(IngestError, match=says):
        parse_request(body)
