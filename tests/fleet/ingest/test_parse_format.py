"""A batch's ``format`` errors say what is wrong: "upgrade the server" only for a format
newer than this server's (a newer agent). The API fuzzer sent ``"format": 1.0`` and got
"format 1.0 not supported (1..2): upgrade the server", which sends an integrator after the
wrong fix."""

from __future__ import annotations

import pytest
from fieldrx.fleet.ingest.model import IngestError
from fieldrx.fleet.ingest.parse import parse_batch
from fieldrx_edge.protocol import TELEMETRY_FORMAT_VERSION


@pytest.mark.parametrize(
    ("fmt", "says"),
    [
        (TELEMETRY_FORMAT_VERSION + 1, "upgrade the server"),
        (1.0, "must be an integer"),
        (0, "must be an integer"),
        (-3, "must be an integer"),
        ("2", "must be an integer"),
        (True, "must be an integer"),
    ],
)
def test_format_errors_name_the_fix(fmt: object, says: str) -> None:
    import json

    with pytest.raises(IngestError, match=says) as exc:
        parse_batch(json.dumps({"format": fmt, "records": []}))
    if says != "upgrade the server":
        assert "upgrade" not in str(exc.value)


def test_every_known_format_parses() -> None:
    for fmt in range(1, TELEMETRY_FORMAT_VERSION + 1):
        assert parse_batch(f'{{"format": {fmt}, "records": []}}').records == []
