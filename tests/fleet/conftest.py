from __future__ import annotations

import pytest

from tests.fleet.helpers import JobFixture, make_job


@pytest.fixture()
def job(org) -> JobFixture:  # noqa: ANN001
    return make_job(org.id, state="running")
