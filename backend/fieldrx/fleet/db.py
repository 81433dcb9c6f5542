"""Raw psycopg connections for ingest, borrowed from the application's SQLAlchemy pool.

COPY BINARY and LISTEN need the driver connection itself; borrowing it from
the engine's pool keeps one pool per process (and its ``jit=off`` option).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import psycopg

from fieldrx.db.session import get_engine


@contextmanager
def raw_connection() -> Iterator[psycopg.Connection[Any]]:
    fairy = get_engine().raw_connection()
    try:
        conn = fairy.driver_connection
        assert isinstance(conn, psycopg.Connection)
        yield conn
    finally:
        fairy.close()
