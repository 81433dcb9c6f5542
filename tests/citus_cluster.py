"""Tests and benches against a Citus coordinator (FIELDRX_TEST_PG) and its workers.

``FIELDRX_TEST_CITUS_WORKERS`` = ``host:port,host:port`` names the workers (each a
PostgreSQL with Citus, PostGIS and pg_partman installed, trusting the coordinator). A
throw-away database then exists on every node, with the extensions, the workers added,
migrated on the coordinator and distributed by ``fieldrx distribute``'s code, as a
deployment does it (docs/scale.md section 2). Unset: plain PostgreSQL, nothing changes.
"""

from __future__ import annotations

import os
import time
import warnings

import psycopg
from sqlalchemy.engine import make_url

WORKERS = [w for w in os.environ.get("FIELDRX_TEST_CITUS_WORKERS", "").split(",") if w]


def _worker_url(url: str, worker: str) -> str:
    u = make_url(url)
    host, port = worker.rsplit(":", 1)
    return str(u.set(host=host, port=int(port)).render_as_string(hide_password=False))


def _dsn(url: str) -> str:
    return make_url(url).set(drivername="postgresql").render_as_string(hide_password=False)


def prepare(url: str) -> None:
    """Before migrating ``url`` (made by ``ensure_database``): the database on each worker,
    citus in every node's copy, the workers added to the coordinator's."""
    from fieldrx.db.bootstrap import ensure_database

    for w in WORKERS:
        ensure_database(_worker_url(url, w))
        with psycopg.connect(_dsn(_worker_url(url, w)), autocommit=True) as conn:
            conn.execute("CREATE EXTENSION IF NOT EXISTS citus")
    u = make_url(url)
    with psycopg.connect(_dsn(url), autocommit=True) as conn:
        conn.execute("CREATE EXTENSION IF NOT EXISTS citus")
        conn.execute("SELECT citus_set_coordinator_host(%s, %s)", (u.host, u.port or 5432))
        for w in WORKERS:
            host, port = w.rsplit(":", 1)
            conn.execute("SELECT citus_add_node(%s, %s)", (host, int(port)))


def distribute_db(url: str) -> None:
    """After migrating: ``fieldrx distribute``."""
    from fieldrx.db.citus import distribute

    with psycopg.connect(_dsn(url), autocommit=True) as conn:
        distribute(conn)


def drop(url: str, timeout_s: float = 60.0) -> None:
    """Drop the database's copies on the workers. Citus's maintenance daemon (a background
    worker that ``WITH (FORCE)`` does not end) may hold a copy a little longer after the
    coordinator's is gone: retried until it lets go, then left with a warning."""
    from fieldrx.db.bootstrap import drop_database

    for w in WORKERS:
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                drop_database(_worker_url(url, w))
                break
            except psycopg.errors.ObjectInUse:
                if time.monotonic() > deadline:
                    warnings.warn(f"{w}: {make_url(url).database} left behind", stacklevel=2)
                    break
                time.sleep(1.0)
