"""Shared fixtures: a throw-away PostGIS database per test session, migrated with Alembic.

Tests talk to the real PostgreSQL/PostGIS on 127.0.0.1:5432 (override with
FIELDRX_TEST_PG, a libpq URL of a superuser; a Citus coordinator with
FIELDRX_TEST_CITUS_WORKERS, tests/citus_cluster.py). Each test creates its own
organisation(s), so tests never see each other's rows.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from dataclasses import dataclass

import pytest

PG = os.environ.get("FIELDRX_TEST_PG", "postgresql://postgres@127.0.0.1:5432")


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--pure",
        action="store_true",
        help="only the quick unit tests: no database, no server processes, not marked slow "
        "(make check)",
    )


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if not config.getoption("pure"):
        return
    keep, drop = [], []
    for item in items:
        impure = "database_url" in getattr(item, "fixturenames", ()) or item.get_closest_marker(
            "slow"
        )
        (drop if impure else keep).append(item)
    items[:] = keep
    config.hook.pytest_deselected(items=drop)


@pytest.hookimpl(tryfirst=True)
def pytest_configure(config: pytest.Config) -> None:
    """pytest-timeout's per-test limit stretched like every other wait (tests.support.scaled):
    a test that passes on a quiet machine must not be killed because the machine is busy."""
    from tests.support import scaled

    base = config.getoption("timeout", None) or float(config.getini("timeout") or 0)
    if base:
        config.option.timeout = scaled(float(base))


@pytest.fixture(scope="session", autouse=True)
def mqtt_broker() -> Iterator[object]:
    """The session's own Mosquitto from the shipped deploy/mosquitto.conf (tests/mqtt_broker.py);
    MQTT_URL points at it, so the API, workers and device-token issuing all use it."""
    from tests.mqtt_broker import ProjectBroker

    broker = ProjectBroker()
    os.environ["MQTT_URL"] = broker.url
    _clear_caches()
    yield broker
    broker.close()


@pytest.fixture(scope="session")
def database_url() -> Iterator[str]:
    """URL of a fresh database with PostGIS and every migration applied."""
    from alembic import command
    from fieldrx.db.bootstrap import alembic_config, drop_database, ensure_database
    from fieldrx.settings import get_settings

    name = f"fieldrx_test_{uuid.uuid4().hex[:10]}"
    url = PG.replace("postgresql://", "postgresql+psycopg://", 1) + f"/{name}"
    from tests import citus_cluster

    ensure_database(url)
    if citus_cluster.WORKERS:  # a Citus coordinator: the nodes first, distributed after
        citus_cluster.prepare(url)
    os.environ["DATABASE_URL"] = url
    _clear_caches()
    command.upgrade(alembic_config(url), "head")
    _sync_task_kinds()  # what fieldrx migrate does after the migrations
    if citus_cluster.WORKERS:
        citus_cluster.distribute_db(url)
    assert get_settings().database_url == url
    yield url
    _clear_caches()
    drop_database(url)
    citus_cluster.drop(url)


def _sync_task_kinds() -> None:
    import fieldrx.tasks.work  # noqa: F401  importing it registers every kind
    from fieldrx.db.session import get_engine
    from fieldrx.tasks.kinds import sync_task_kinds

    sync_task_kinds(get_engine())


def _clear_caches() -> None:
    from fieldrx.db import session as db_session
    from fieldrx.settings import get_settings

    get_settings.cache_clear()
    if db_session.get_engine.cache_info().currsize:
        db_session.get_engine().dispose()
    db_session.get_engine.cache_clear()
    db_session.get_sessionmaker.cache_clear()


@pytest.fixture(scope="session")
def app(database_url: str):  # noqa: ANN201
    from fieldrx.app import create_app

    return create_app()


@pytest.fixture()
def client(app):  # noqa: ANN201
    from fastapi.testclient import TestClient

    with TestClient(app) as c:
        yield c


@pytest.fixture()
def db(database_url: str):  # noqa: ANN201
    from fieldrx.db.session import get_sessionmaker

    with get_sessionmaker()() as session:
        yield session


@dataclass
class Org:
    """An organisation with one user per role; headers() gives bearer headers for a role."""

    id: int
    name: str
    tokens: dict[str, str]
    user_ids: dict[str, int]
    password: str = "correct horse battery"

    def headers(self, role: str = "agronomist") -> dict[str, str]:
        return {"Authorization": f"Bearer {self.tokens[role]}"}

    def email(self, role: str) -> str:
        return f"{role}@{self.name}.test"


@pytest.fixture()
def make_org(database_url: str):  # noqa: ANN201
    """Factory: a new organisation with admin, agronomist and viewer users and tokens."""
    from fieldrx.auth.service import (
        add_membership,
        create_organisation,
        create_user,
        issue_user_token,
    )
    from fieldrx.db.session import get_sessionmaker

    def factory() -> Org:
        name = f"org-{uuid.uuid4().hex[:8]}"
        with get_sessionmaker()() as s:
            org = create_organisation(s, name)
            tokens, ids = {}, {}
            for role in ("admin", "agronomist", "viewer"):
                user = create_user(s, f"{role}@{name}.test", Org.password, role.title())
                add_membership(s, user, org, role)
                tokens[role], _ = issue_user_token(s, user.id, org.id, role)
                ids[role] = user.id
            s.commit()
            return Org(org.id, name, tokens, ids)

    return factory


@pytest.fixture()
def org(make_org) -> Org:  # noqa: ANN001
    return make_org()


@pytest.fixture()
def job(org):  # noqa: ANN001, ANN201
    """A running job of `org` (tests/fleet/helpers.py): the telemetry tests of the API and
    of the fleet's ingest both post against one."""
    from tests.fleet.helpers import make_job

    return make_job(org.id, state="running")
