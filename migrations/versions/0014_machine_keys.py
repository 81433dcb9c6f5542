"""Per-cell results carry their machine: ``job_cells_applied.machine_id``.

Why: to distribute telemetry by machine (Citus), every table the ingest path writes must
hold the distribution column, so a batch is one single-shard transaction co-located with
the machine's telemetry. ``job_cell_records`` (0011) has it; ``job_cells_applied`` (per
cell sums, written by every batch) had only ``job_id``. It gains ``machine_id``, filled
from its job for the rows already there (none is lost), and its key becomes
``(machine_id, job_id, seq)`` (a distributed table's key must hold the distribution
column). A foreign key ``(machine_id, job_id) -> jobs (machine_id, id)`` keeps the copy
true to the job (``jobs`` gets the unique key it needs; ON UPDATE CASCADE should a job
ever move to another machine).

Downgrade: the key ``(job_id, seq)`` and the job foreign key again, the column dropped.

Revision ID: 0014_machine_keys
Revises: 0013_cells
"""

from __future__ import annotations

from collections.abc import Sequence

from alembic import op

revision: str = "0014_machine_keys"
down_revision: str | Sequence[str] | None = "0013_cells"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.execute("ALTER TABLE jobs ADD CONSTRAINT uq_jobs_machine_id_id UNIQUE (machine_id, id)")
    op.execute("ALTER TABLE job_cells_applied ADD COLUMN machine_id integer")
    op.execute(
        "UPDATE job_cells_applied a SET machine_id = j.machine_id FROM jobs j WHERE j.id = a.job_id"
    )
    op.execute(
        "ALTER TABLE job_cells_applied ALTER COLUMN machine_id SET NOT NULL,"
        " DROP CONSTRAINT job_cells_applied_pkey,"
        " DROP CONSTRAINT job_cells_applied_job_id_fkey,"
        " ADD CONSTRAINT job_cells_applied_pkey PRIMARY KEY (machine_id, job_id, seq),"
        " ADD CONSTRAINT job_cells_applied_machine_job_fkey FOREIGN KEY (machine_id, job_id)"
        "  REFERENCES jobs (machine_id, id) ON DELETE CASCADE ON UPDATE CASCADE"
    )


def downgrade() -> None:
    op.execute(
        "ALTER TABLE job_cells_applied DROP CONSTRAINT job_cells_applied_machine_job_fkey,"
        " DROP CONSTRAINT job_cells_applied_pkey,"
        " ADD CONSTRAINT job_cells_applied_pkey PRIMARY KEY (job_id, seq),"
        " ADD CONSTRAINT job_cells_applied_job_id_fkey FOREIGN KEY (job_id)"
        "  REFERENCES jobs (id) ON DELETE CASCADE,"
        " DROP COLUMN machine_id"
    )
    op.execute("ALTER TABLE jobs DROP CONSTRAINT uq_jobs_machine_id_id")
