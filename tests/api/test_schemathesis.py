"""Property-based API fuzzing (schemathesis) against a real API process: no answer is a 5xx.

Every operation of the OpenAPI schema gets a few generated requests (bounded
budget: ``MAX_EXAMPLES`` each, about a minute in all) with an admin token of a
throw-away organisation. Operations that would end the session (logout,
revoking tokens) are left out so the rest keep running authenticated.
"""

from __future__ import annotations

import uuid
from collections.abc import Iterator

import pytest
import schemathesis
from hypothesis import HealthCheck, Phase, settings

from tests.fleet.procs import start_api

MAX_EXAMPLES = 8


@pytest.fixture(scope="module")
def fuzz_api(database_url: str) -> Iterator[tuple[str, dict[str, str]]]:
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
        user = create_user(s, f"admin@{name}.test", "fuzz fuzz fuzz", "Fuzz")
        add_membership(s, user, org, "admin")
        token, _ = issue_user_token(s, user.id, org.id, "admin")
        s.commit()
    proc, url = start_api(database_url)
    yield url, {"Authorization": f"Bearer {token}"}
    out = proc.stop()
    assert "Traceback" not in out, out[-3000:]


def test_no_server_errors(fuzz_api: tuple[str, dict[str, str]]) -> None:
    from hypothesis import given

    url, headers = fuzz_api
    schema = (
        schemathesis.openapi.from_url(f"{url}/api/v1/openapi.json")
        .exclude(path_regex=r"/auth/(logout|tokens/\{token_id\})$")
        .exclude(path_regex=r"/live$")
    )
    failures: list[str] = []
    codes: list[int] = []
    n_ops = 0
    for result in schema.get_all_operations():
        operation = result.ok()
        n_ops += 1

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
            response = case.call(headers=headers, timeout=30)
            codes.append(response.status_code)
            if response.status_code >= 500:
                failures.append(
                    f"{case.method} {case.formatted_path} {case.query or ''} -> "
                    f"{response.status_code}: {response.text[:300]}"
                )

        run()
    assert n_ops > 40
    assert sum(200 <= c < 300 for c in codes) > 20, codes  # authenticated, not all refused
    assert not failures, "\n".join(failures)
