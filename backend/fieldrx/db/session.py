"""Engine and session factory.

JIT is switched off on every application connection: on this class of machine
it made spatial aggregations 4-5x slower (docs/architecture.md, "Stack notes").
"""

from __future__ import annotations

from collections.abc import Iterator
from functools import lru_cache

from sqlalchemy import Engine, create_engine, text
from sqlalchemy.orm import Session, sessionmaker

from fieldrx.settings import get_settings


def make_engine(url: str) -> Engine:
    return create_engine(
        url,
        pool_pre_ping=True,
        pool_size=10,
        max_overflow=20,
        connect_args={"options": "-c jit=off"},
    )


def limit_session(session: Session, time_limit_s: float) -> None:
    """Bound a heavy-work child's database session by its time limit: no statement and no
    idle transaction outlives it, and PostgreSQL checks every second that the client is
    still connected, so a killed child's running statement is cancelled and its locks
    released at once instead of when the statement would have finished."""
    ms = max(1000, int(time_limit_s * 1000))
    session.execute(text(f"SET statement_timeout = {ms}"))
    session.execute(text(f"SET idle_in_transaction_session_timeout = {ms}"))
    session.execute(text("SET client_connection_check_interval = 1000"))


@lru_cache
def get_engine() -> Engine:
    return make_engine(get_settings().database_url)


@lru_cache
def get_sessionmaker() -> sessionmaker[Session]:
    return sessionmaker(bind=get_engine(), expire_on_commit=False)


def get_session() -> Iterator[Session]:
    """FastAPI dependency: one session (and one transaction per write) per request."""
    session = get_sessionmaker()()
    try:
        yield session
    finally:
        session.close()


def raw_dsn(url: str | None = None) -> str:
    """libpq DSN (for psycopg COPY and LISTEN) from the SQLAlchemy URL."""
    url = url or get_settings().database_url
    return url.replace("postgresql+psycopg://", "postgresql://", 1)
