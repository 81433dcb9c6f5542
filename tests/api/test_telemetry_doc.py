"""The OpenAPI description of ``POST /api/v1/telemetry`` is the endpoint's real contract.

The route reads its body itself (``fleet.ingest.parse.parse_request``), so nothing checks the
document against it but these tests: every request form the parser takes (telemetry
batch, cell batch, several batches) is offered, with the parser's rules; the records'
required fields are the protocol's; the 200 answer offers the single ack and
``{"acks": [...]}``; every ``$ref`` of the document resolves; and real answers of the
endpoint validate against the documented schema.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import fields
from typing import Any

import jsonschema_rs
import orjson
import pytest
from fieldrx_edge.cell_records import CellRecord
from fieldrx_edge.protocol import (
    MAX_BATCHES,
    STREAM_RE,
    ProtocolError,
    TelemetryAck,
    TelemetryRecord,
)

from tests.fleet.helpers import JobFixture, make_job, record

PATH = "/api/v1/telemetry"


@pytest.fixture(scope="module")
def document(app) -> dict[str, Any]:  # noqa: ANN001
    return app.openapi()


@pytest.fixture()
def job(org) -> JobFixture:  # noqa: ANN001
    return make_job(org.id, state="running")


def _resolve(document: dict[str, Any], ref: str) -> Any:
    """A local ``$ref`` (JSON pointer) of the document; KeyError when it points nowhere."""
    assert ref.startswith("#/"), ref
    node: Any = document
    for part in ref[2:].split("/"):
        node = node[part.replace("~1", "/").replace("~0", "~")]
    return node


def _refs(node: Any) -> Iterator[str]:
    if isinstance(node, dict):
        for k, v in node.items():
            if k == "$ref" and isinstance(v, str):
                yield v
            else:
                yield from _refs(v)
    elif isinstance(node, list):
        for v in node:
            yield from _refs(v)


def _deref(document: dict[str, Any], schema: dict[str, Any]) -> dict[str, Any]:
    return _resolve(document, schema["$ref"]) if "$ref" in schema else schema


def _operation(document: dict[str, Any]) -> dict[str, Any]:
    return document["paths"][PATH]["post"]


def _request_forms(document: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The request body's alternatives by their ``kind``."""
    body = _operation(document)["requestBody"]["content"]["application/json"]["schema"]
    forms = [_deref(document, s) for s in body.get("anyOf") or body.get("oneOf") or [body]]
    out = {}
    for f in forms:
        kind = f.get("properties", {}).get("kind", {})
        out[kind.get("const", kind.get("default"))] = f
    return out


def _validator(document: dict[str, Any], schema: dict[str, Any]) -> Any:
    """A 2020-12 validator of ``schema`` whose ``#/components/...`` refs resolve in the
    document (OpenAPI 3.1 schemas are JSON Schema 2020-12)."""
    return jsonschema_rs.Draft202012Validator({**schema, "components": document["components"]})


def test_every_ref_in_the_document_resolves(document: dict[str, Any]) -> None:
    refs = set(_refs(document))
    assert len(refs) > 100
    dangling = []
    for ref in sorted(refs):
        try:
            _resolve(document, ref)
        except (KeyError, AssertionError):
            dangling.append(ref)
    assert not dangling, dangling
    assert not [r for r in refs if not r.startswith("#/components/schemas/")], refs


def test_request_body_offers_every_batch_form_with_the_parser_rules(
    document: dict[str, Any],
) -> None:
    forms = _request_forms(document)
    assert set(forms) == {"telemetry", "cells", "batches"}, list(forms)
    track, cells, multi = forms["telemetry"], forms["cells"], forms["batches"]

    stream = track["properties"]["stream"]["anyOf"]
    assert {"type": "null"} in stream  # format 1: no stream, the legacy one
    assert [s["pattern"] for s in stream if "pattern" in s] == [STREAM_RE.pattern]
    fmt = track["properties"]["format"]
    assert (fmt["minimum"], fmt["maximum"], fmt["default"]) == (1, 2, 1)
    assert track["required"] == ["records"]

    assert cells["properties"]["format"]["const"] == 3
    assert cells["properties"]["stream"]["pattern"] == STREAM_RE.pattern
    assert set(cells["required"]) == {"format", "kind", "stream", "records"}
    for form in (track, cells):
        start = form["properties"]["stream_start"]
        assert (start["minimum"], start["maximum"]) == (1, 2**63 - 1)

    assert multi["properties"]["format"]["const"] == 3
    batches = multi["properties"]["batches"]
    assert (batches["minItems"], batches["maxItems"]) == (1, MAX_BATCHES)
    items = [_deref(document, s) for s in batches["items"]["anyOf"]]
    assert items == [track, cells]  # batches do not nest


@pytest.mark.parametrize("cls", [TelemetryRecord, CellRecord], ids=lambda c: c.__name__)
def test_records_are_the_protocol_records(document: dict[str, Any], cls: type) -> None:
    """The record schemas carry the dataclass's fields, are closed (``from_dict`` rejects an
    unknown field) and require exactly what ``from_dict`` requires: a record of the required
    fields alone parses, and one without any of them does not."""
    kind = "telemetry" if cls is TelemetryRecord else "cells"
    batch = _request_forms(document)[kind]
    schema = _deref(document, batch["properties"]["records"]["items"])
    assert set(schema["properties"]) == {f.name for f in fields(cls)}
    assert schema["additionalProperties"] is False
    sample = {"integer": 1, "number": 1.7e9}
    minimal = {n: sample[schema["properties"][n]["type"]] for n in schema["required"]}
    cls.from_dict(minimal)
    for name in minimal:
        with pytest.raises(ProtocolError, match=f"missing required field '{name}'"):
            cls.from_dict({k: v for k, v in minimal.items() if k != name})


def test_answer_offers_one_ack_or_acks(document: dict[str, Any]) -> None:
    ok = _operation(document)["responses"]["200"]["content"]["application/json"]["schema"]
    answers = [_deref(document, s) for s in ok["anyOf"]]
    ack, acks = sorted(answers, key=lambda s: "acks" in s["properties"])
    assert _deref(document, acks["properties"]["acks"]["items"]) == ack
    assert acks["properties"]["acks"]["maxItems"] == MAX_BATCHES
    assert set(ack["properties"]) == {f.name for f in fields(TelemetryAck)} | {"error"}
    assert set(ack["required"]) == {"machine_id", "acked_seq", "stored", "duplicates", "rejected"}


def test_real_answers_validate_against_the_documented_schemas(
    client,  # noqa: ANN001
    document: dict[str, Any],
    job: JobFixture,
) -> None:
    """Every request form, as agents send it, is valid under the documented body schema,
    and the endpoint's answers (one ack of each kind, several acks, an error ack) are
    valid under the documented 200 schema; the validator does refuse a wrong answer."""
    from fieldrx.fleet.ingest.model import Batch
    from fieldrx.fleet.multibatch import error_ack

    op = _operation(document)
    request = _validator(document, op["requestBody"]["content"]["application/json"]["schema"])
    answer = _validator(document, op["responses"]["200"]["content"]["application/json"]["schema"])
    t = time.time() - 100
    track = {
        "format": 2, "stream": "docTrack", "stream_start": 1,
        "records": [record(job, i, t=t + i, cell=None) for i in range(1, 4)],
    }  # fmt: skip
    cell = {
        "machine_id": job.machine_id, "seq": 1, "job_id": job.job_id, "cell_seq": 0,
        "t_entry": t, "t_exit": t + 1.5, "n_fixes": 15, "worked_s": 1.5, "mass_g": 10.0,
        "driven_m": 5.0, "mean_speed_m_s": 1.8, "mean_target_rate_kg_ha": 300.0,
        "mean_applied_rate_kg_ha": 298.0, "flags": [],
    }  # fmt: skip
    cells = {
        "format": 3, "kind": "cells", "stream": "docCells", "stream_start": 1,
        "records": [cell, {**cell, "seq": 2, "mass_g": -1.0}],  # the second is rejected
    }  # fmt: skip
    bodies = [
        {"format": 3, "kind": "batches", "batches": [track, cells]},
        # format 1 (no stream); the second record is rejected (lon out of range)
        {"records": [record(job, 1, t=t, cell=None), record(job, 2, t=t + 1, lon=500.0)]},
        {**track, "records": track["records"][:1]},
    ]
    answers = []
    for body in bodies:
        request.validate(body)
        r = client.post(PATH, json=body, headers=job.device_headers)
        assert r.status_code == 200, r.text
        answers.append(r.json())
    multi, legacy, single = answers
    assert [a["stored"] for a in multi["acks"]] == [3, 1], multi
    assert multi["acks"][1]["rejected"][0]["seq"] == 2, multi
    assert "stream" not in legacy and legacy["rejected"], legacy
    failed = error_ack(
        job.machine_id, Batch([], "docCells", 1, True, "cells"), "batches[1]", ValueError("no")
    )
    answers.append({"acks": [single, orjson.loads(failed)]})
    for a in answers:
        answer.validate(a)

    assert not answer.is_valid({"acks": []})
    assert not answer.is_valid({**single, "unknown": 1})
    for wrong in (
        {"format": 3, "kind": "batches", "batches": [bodies[0]]},  # batches do not nest
        {"format": 3, "kind": "cells", "records": []},  # a cells batch names its stream
        {**track, "stream": "no spaces"},
        {**track, "stream_start": 0},
    ):
        assert not request.is_valid(wrong), wrong
