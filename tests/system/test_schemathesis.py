"""Property-based API fuzzing (schemathesis) against a real API process: no answer is a 5xx,
and every answer conforms to the OpenAPI document (status code, content type, schema).

Every operation of the document gets a few generated requests (``MAX_EXAMPLES`` each,
about a minute in all) with a writer (agronomist) token of a throw-away organisation
that owns one of each main resource (farm, field, plan, prescription, machine, job):
generated ids are replaced by those, so the answers are real 200s and the response
schemas are exercised, not only 404s. DELETEs run last. Operations that would end the
session (logout, revoking tokens) are left out.
"""

from __future__ import annotations

import time
import uuid
from collections.abc import Iterator
from typing import Any

import httpx
import pytest
import schemathesis
from hypothesis import HealthCheck, Phase, given, settings
from schemathesis.checks import (
    content_type_conformance,
    not_a_server_error,
    response_schema_conformance,
    status_code_conformance,
)
from schemathesis.core.failures import FailureGroup

from tests.fleet.procs import start_api
from tests.support import SMALL_PLOT, feature, machine_body, scaled

MAX_EXAMPLES = 8
CHECKS = [
    not_a_server_error,
    status_code_conformance,
    content_type_conformance,
    response_schema_conformance,
]


def _fuzz_settings(max_examples: int) -> Any:
    """Hypothesis settings of every fuzzing run here: repeatable (derandomised, no example
    database), no deadline (the API answers over the network), every health check off."""
    return settings(
        max_examples=max_examples,
        deadline=None,
        phases=[Phase.explicit, Phase.generate],
        suppress_health_check=list(HealthCheck),
        derandomize=True,
        database=None,
    )


def _seed(url: str, headers: dict[str, str]) -> dict[str, int]:
    """One of each main resource, created through the API as a farm software would."""

    def post(path: str, body: dict[str, Any]) -> dict[str, Any]:
        r = httpx.post(f"{url}/api/v1{path}", json=body, headers=headers, timeout=scaled(60))
        assert r.status_code == 201, (path, r.text)
        return r.json()

    farm = post("/farms", {"name": "Fuzz farm"})
    field = post("/fields", feature(SMALL_PLOT, farm_id=farm["id"]))
    plan = post(f"/fields/{field['id']}/plans", {"swath_width_m": 2.3, "cell_length_m": 5})
    rx = post(
        f"/plans/{plan['id']}/prescriptions",
        {"model": "uniform", "params": {"rate_kg_ha": 300}, "name": "fuzz"},
    )
    machine = post("/machines", machine_body("Fuzz spreader"))
    job = post(
        "/jobs",
        {"prescription_id": rx["id"], "machine_id": machine["id"], "confirm_flagged": True},
    )
    return {
        "farm_id": farm["id"],
        "field_id": field["id"],
        "plan_id": plan["id"],
        "rx_id": rx["id"],
        "prescription_id": rx["id"],
        "version": 1,
        "machine_id": machine["id"],
        "job_id": job["id"],
    }


@pytest.fixture(scope="module")
def fuzz_api(database_url: str) -> Iterator[tuple[str, dict[str, str], dict[str, int]]]:
    from fieldrx.auth.service import (
        add_membership,
        create_organisation,
        create_user,
        issue_user_token,
    )
    from fieldrx.db.session import get_sessionmaker

    name = f"fuzz-{uuid.uuid4().hex[:8]}"
    with get_sessionmaker()() as s:
        org = create_organisation(s, name)
        user = create_user(s, f"agronomist@{name}.test", "fuzz fuzz fuzz", "Fuzz")
        add_membership(s, user, org, "agronomist")
        token, _ = issue_user_token(s, user.id, org.id, "agronomist")
        s.commit()
    proc, url = start_api(database_url)
    headers = {"Authorization": f"Bearer {token}"}
    ids = _seed(url, headers)
    yield url, headers, ids
    out = proc.stop()
    assert "Traceback" not in out, out[-3000:]


def test_no_server_errors_and_answers_match_the_schema(
    fuzz_api: tuple[str, dict[str, str], dict[str, int]],
) -> None:
    url, headers, ids = fuzz_api
    schema = (
        schemathesis.openapi.from_url(f"{url}/api/v1/openapi.json")
        .exclude(path_regex=r"/auth/(logout|tokens/\{token_id\})$")
        .exclude(path_regex=r"/live$")
    )
    operations = [r.ok() for r in schema.get_all_operations()]
    operations.sort(key=lambda op: op.method.upper() == "DELETE")  # deletes last
    failures: list[str] = []
    codes: list[int] = []
    started = time.monotonic()
    cpu_started = time.process_time()

    for operation in operations:

        @_fuzz_settings(MAX_EXAMPLES)
        @given(case=operation.as_strategy())
        def run(case: schemathesis.Case) -> None:
            for key in list(case.path_parameters or {}):
                if key in ids:  # the seeded resources, so answers are real, not 404s
                    case.path_parameters[key] = ids[key]
            try:
                response = case.call_and_validate(
                    headers=headers, checks=CHECKS, timeout=scaled(30)
                )
            except FailureGroup as exc:  # one line per failed check
                failures.append(f"{case.method} {case.formatted_path} {case.query or ''}: {exc}")
                return
            codes.append(response.status_code)

        run()
    elapsed = time.monotonic() - started
    cpu = time.process_time() - cpu_started
    print(f"fuzzed {len(operations)} operations in {elapsed:.0f} s ({cpu:.0f} s of CPU here)")
    assert len(operations) > 60
    ok = sum(200 <= c < 300 for c in codes)
    assert ok > 60, codes  # authenticated and seeded: most operations answered for real
    # the run stays bounded: generating the cases is this process's CPU work (8 s here),
    # which a busy machine does not change; its wall time does (23 s quiet, 138 s beside 6
    # busy processes), so that bound scales with the machine like every other wait
    assert cpu < 40, f"generating the cases took {cpu:.0f} s of CPU"
    assert elapsed < scaled(120), f"took {elapsed:.0f} s"
    assert not failures, "\n\n".join(dict.fromkeys(f[:1500] for f in failures))


INGEST_EXAMPLES = 150


def test_device_ingest_fuzzed_with_a_device_token(
    fuzz_api: tuple[str, dict[str, str], dict[str, int]],
) -> None:
    """``POST /telemetry`` with the job's machine's device token (the test above sends a
    person's token: every request was a 403, the documented body never reached ingest):
    bodies generated from the documented request schema (every batch form, any record
    values the schema allows) get no 5xx, and every answer conforms to the document."""
    url, headers, _ = fuzz_api
    ids = _seed(url, headers)  # its own: the test above deletes the module's seeded ones
    r = httpx.post(
        f"{url}/api/v1/machines/{ids['machine_id']}/device-token",
        headers=headers,
        timeout=scaled(30),
    )
    assert r.status_code in (200, 201), r.text
    device = {"Authorization": f"Bearer {r.json()['token']}"}
    schema = schemathesis.openapi.from_url(f"{url}/api/v1/openapi.json").include(
        path_regex=r"/telemetry$", method="POST"
    )
    (operation,) = [r.ok() for r in schema.get_all_operations()]
    failures: list[str] = []
    codes: list[int] = []

    @_fuzz_settings(INGEST_EXAMPLES)
    @given(case=operation.as_strategy())
    def run(case: schemathesis.Case) -> None:
        _own_records(case.body, ids)
        try:
            response = case.call_and_validate(headers=device, checks=CHECKS, timeout=scaled(30))
        except FailureGroup as exc:
            failures.append(f"{case.body!r:.600}: {exc}")
            return
        codes.append(response.status_code)

    run()
    assert not failures, "\n\n".join(dict.fromkeys(f[:2500] for f in failures[:5]))
    assert sum(c == 200 for c in codes) > INGEST_EXAMPLES // 2, codes  # ingest answered


def _own_records(body: Any, ids: dict[str, int]) -> None:
    """Records of the device's own machine and job (generated ids are another machine's
    and get the record rejected before the database): the values the schema allows then
    reach validation's end, the COPY, the per-cell sums and the acks."""
    if not isinstance(body, dict):
        return
    batches = body.get("batches") if body.get("kind") == "batches" else [body]
    for batch in batches if isinstance(batches, list) else []:
        for rec in batch.get("records", []) if isinstance(batch, dict) else []:
            if isinstance(rec, dict):
                rec["machine_id"] = ids["machine_id"]
                if "job_id" in rec:
                    rec["job_id"] = ids["job_id"]
