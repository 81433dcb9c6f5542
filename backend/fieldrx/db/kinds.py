"""The ``job_kinds`` rows, written from ``fieldrx_edge.jobkinds.registry``.

``jobs.kind`` is a foreign key to ``job_kinds`` (migration 0019), so the database accepts
exactly the registry's kinds without a migration per kind: every ``fieldrx migrate`` (and
every Alembic upgrade, ``migrations/env.py``) upserts the registry's rows. A kind gone from
the registry keeps its row: jobs of it may still exist.
"""

from __future__ import annotations

from typing import Any

from fieldrx_edge.jobkinds.registry import kinds
from sqlalchemy import text


def sync_job_kinds(connection: Any) -> int:
    """Upsert the registry's kinds into ``job_kinds`` (when the table exists); the count."""
    if connection.scalar(text("SELECT to_regclass('job_kinds')")) is None:
        return 0
    rows = [{"name": k.name, "rates_from": k.rates_from} for k in kinds()]
    connection.execute(
        text(
            "INSERT INTO job_kinds (name, rates_from) VALUES (:name, :rates_from)"
            " ON CONFLICT (name) DO UPDATE SET rates_from = EXCLUDED.rates_from"
            " WHERE job_kinds.rates_from <> EXCLUDED.rates_from"
        ),
        rows,
    )
    return len(rows)
