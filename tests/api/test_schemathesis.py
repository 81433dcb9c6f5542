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
from tests.support import SMALL_PLOT, feature, machine_body

MAX_EXAMPLES = 8
CHECKS = [
    not_a_server_error,
    status_code_conformance,
    content_type_conformance,
    response_schema_conformance,
]


def _seed(url: str, headers: dict[str, str]) -> dict[str, int]:
    """One of each main resource, created through the API as a farm software would."""

    def post(path: str, body: dict[str, Any]) -> dict[str, Any]:
        r = httpx.post(f"{url}/api/v1{path}", json=body, headers=headers, timeout=60)
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

    for operation in operations:

        @settings(
            max_examples=MAX_EXAMPLES,
            deadline=None,
            phases=[Phase.explicit, Phase.generate],
            suppress_health_check=list(HealthCheck),
            derandomize=True,
            database=None,
        )
        @given(case=operation.as_strategy())
        def run(case: schemathesis.Case) -> None:
            for key in list(case.path_parameters or {}):
                if key in ids:  # the seeded resources, so answers are real, not 404s
                    case.path_parameters[key] = ids[key]
            try:
                response = case.call_and_validate(headers=headers, checks=CHECKS, timeout=30)
            except FailureGroup as exc:  # one line per failed check
                failures.append(f"{case.method} {case.formatted_path} {case.query or ''}: {exc}")
                return
            codes.append(response.status_code)

        run()
    elapsed = time.monotonic() - started
    assert len(operations) > 60
    ok = sum(200 <= c < 300 for c in codes)
    assert ok > 60, codes  # authenticated and seeded: most operations answered for real
    assert elapsed < 120, f"took {elapsed:.0f} s"
    assert not failures, "\n\n".join(dict.fromkeys(f[:1500] for f in failures))
