"""Raw psycopg connections for ingest: a small per-process pool, keyed by DSN.

COPY BINARY needs the driver connection itself. The application's SQLAlchemy
pool pings on every checkout and rolls back on return; at hundreds of batches
per second those round trips cost more than the batch's own statements, so
ingest keeps its own LIFO pool of plain connections (``jit=off`` as everywhere).
A connection that raised is closed, not reused.

The connections are in autocommit mode: a single statement (the device-token check)
is its own transaction in one round trip instead of three (BEGIN, statement,
COMMIT), and ingest sends its own BEGIN and COMMIT inside pipelines
(``fleet.ingest.store.pipelined``). Every multi-statement use opens ``conn.transaction()``.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import psycopg

from fieldrx.db.session import raw_dsn

MAX_IDLE = 16

_lock = threading.Lock()
_idle: dict[str, list[psycopg.Connection[Any]]] = {}


def connect(dsn: str) -> psycopg.Connection[Any]:
    """A raw ingest connection (autocommit, ``jit=off``)."""
    return psycopg.connect(dsn, options="-c jit=off", autocommit=True)


@contextmanager
def raw_connection(dsn: str | None = None) -> Iterator[psycopg.Connection[Any]]:
    dsn = dsn or raw_dsn()
    with _lock:
        stack = _idle.setdefault(dsn, [])
        conn = stack.pop() if stack else None
    if conn is None or conn.closed:
        conn = connect(dsn)
    try:
        yield conn
    except BaseException:
        conn.close()
        raise
    if conn.info.transaction_status != psycopg.pq.TransactionStatus.IDLE:
        conn.rollback()
    with _lock:
        stack = _idle.setdefault(dsn, [])
        if len(stack) < MAX_IDLE:
            stack.append(conn)
            return
    conn.close()
