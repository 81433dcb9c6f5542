"""Job kinds as rows: ``job_kinds``, and ``jobs.kind`` a foreign key to it.

Why: the kinds are a registry in code (``fieldrx_edge.jobkinds.registry``); a CHECK listing
them needed a migration for every new kind. The table is filled from the registry by every
upgrade (``migrations/env.py`` -> ``fieldrx.db.kinds.sync_job_kinds``); the rows below are
the kinds of this revision's time. ``ck_job_source`` can no longer name a kind: a job keeps
a prescription (version) or a plan, and which one its kind needs is the API's check. Past
one node the table is a reference table (``db/citus.py``).

Revision ID: 0019_job_kinds_table
Revises: 0018_task_kinds
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0019_job_kinds_table"
down_revision: str | Sequence[str] | None = "0018_task_kinds"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

KINDS_0009 = (
    ("prescription_map", "cells"),
    ("ndvi_topdress", "sensors"),
    ("seeding_depth", "sensors"),
)


def upgrade() -> None:
    table = op.create_table(
        "job_kinds",
        sa.Column("name", sa.String(32), primary_key=True),
        sa.Column("rates_from", sa.String(16), nullable=False),
        sa.CheckConstraint("rates_from IN ('cells', 'sensors')", name="ck_job_kinds_rates_from"),
    )
    op.bulk_insert(table, [{"name": n, "rates_from": r} for n, r in KINDS_0009])
    op.drop_constraint("ck_job_kind", "jobs", type_="check")
    op.drop_constraint("ck_job_source", "jobs", type_="check")
    op.create_check_constraint(
        "ck_job_source",
        "jobs",
        "(prescription_id IS NOT NULL AND prescription_version IS NOT NULL)"
        " OR plan_id IS NOT NULL",
    )
    op.create_foreign_key("fk_jobs_kind", "jobs", "job_kinds", ["kind"], ["name"])


def downgrade() -> None:
    names = tuple(n for n, _ in KINDS_0009)
    op.execute(sa.text("DELETE FROM jobs WHERE kind NOT IN :names").bindparams(
        sa.bindparam("names", names, expanding=True)
    ))
    op.drop_constraint("fk_jobs_kind", "jobs", type_="foreignkey")
    op.drop_constraint("ck_job_source", "jobs", type_="check")
    op.create_check_constraint(
        "ck_job_source",
        "jobs",
        "(kind = 'prescription_map' AND prescription_id IS NOT NULL"
        " AND prescription_version IS NOT NULL)"
        " OR (kind <> 'prescription_map' AND plan_id IS NOT NULL)",
    )
    op.create_check_constraint("ck_job_kind", "jobs", f"kind IN {names}")
    op.drop_table("job_kinds")
