"""Machine-keyed tables keyed and referenced through ``machine_id`` (distributable by Citus).

Why: past one node the machine-keyed tables are distributed by machine (Citus,
``fieldrx distribute``, docs/scale.md section 2). Citus refuses, for a distributed table:
a primary or unique key without the distribution column; a foreign key between two
distributed tables that does not hold it on both sides; a foreign key from a reference or
coordinator table into a distributed one; a foreign key from a distributed table to a
coordinator table; ``ON UPDATE CASCADE``. Each of these was met on a real cluster. So:

* ``jobs`` and ``alerts`` are keyed ``(machine_id, id)`` (ids stay globally unique from
  their sequences; a plain index on ``id`` serves lookups by id);
* ``job_events`` carries its job's ``machine_id`` (filled from the job) and is keyed
  ``(machine_id, id)``; it and ``job_cell_records`` reference their job by
  ``(machine_id, job_id)``; ``job_cells_applied`` loses ``ON UPDATE CASCADE`` (a job never
  moves to another machine: Citus cannot move a row between shards anyway);
* foreign keys from coordinator tables into the machine-keyed set go
  (``api_tokens.machine_id``, ``prescriptions.machine_id``, ``job_events.by_machine_id``),
  and so do those from ``jobs`` to coordinator tables (``plan_id``, ``prescription_id``):
  their cascades are done by the application in the deleting transaction
  (``fieldrx.services.evidence.delete_jobs`` and the machine delete);
* the plan-cell shape check moves from the ``plan_cells`` parent to each partition: under
  Citus the parent's shard names its CHECK with a shard suffix, and a partition created by
  the ``plans`` trigger then "is missing constraint" and is refused.

Downgrade restores the keys, the foreign keys and the parent's CHECK.

Revision ID: 0017_i31_citus_keys
Revises: 0017_i32_field_features
"""

from __future__ import annotations

from collections.abc import Sequence

from alembic import op

revision: str = "0017_i31_citus_keys"
down_revision: str | Sequence[str] | None = "0017_i32_field_features"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

SHAPE = "CHECK (GeometryType(geom) IN ('POLYGON', 'MULTIPOLYGON'))"

# the plans trigger of 0002, with the shape check added to each new partition
PARTITION_FN = """
CREATE OR REPLACE FUNCTION fieldrx_plan_cells_partition() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
  IF coalesce(current_setting('fieldrx.bulk_plan_cells', true), '') <> 'on' THEN
    EXECUTE format('CREATE TABLE %I PARTITION OF plan_cells FOR VALUES IN (%s)',
                   'plan_cells_p' || NEW.id, NEW.id);
    EXECUTE format('ALTER TABLE %I ADD CONSTRAINT %I %s', 'plan_cells_p' || NEW.id,
                   'plan_cells_p' || NEW.id || '_geom_polygonal', {shape});
  END IF;
  RETURN NULL;
END $$;
"""

OLD_PARTITION_FN = """
CREATE OR REPLACE FUNCTION fieldrx_plan_cells_partition() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
  IF coalesce(current_setting('fieldrx.bulk_plan_cells', true), '') <> 'on' THEN
    EXECUTE format('CREATE TABLE %I PARTITION OF plan_cells FOR VALUES IN (%s)',
                   'plan_cells_p' || NEW.id, NEW.id);
  END IF;
  RETURN NULL;
END $$;
"""

CHILDREN = (
    "SELECT c.relname FROM pg_inherits i JOIN pg_class c ON c.oid = i.inhrelid"
    " WHERE i.inhparent = 'plan_cells'::regclass"
)


def _plan_cells_up() -> None:
    op.execute("ALTER TABLE plan_cells DROP CONSTRAINT plan_cells_geom_polygonal")
    op.execute(
        f"""
        DO $$ DECLARE r record; BEGIN
          FOR r IN {CHILDREN} LOOP
            EXECUTE format($f$ALTER TABLE %I ADD CONSTRAINT %I {SHAPE}$f$, r.relname,
                           r.relname || '_geom_polygonal');
          END LOOP;
        END $$
        """
    )
    op.execute(PARTITION_FN.replace("{shape}", "$c$" + SHAPE + "$c$"))


def _plan_cells_down() -> None:
    op.execute(OLD_PARTITION_FN)
    op.execute(
        f"""
        DO $$ DECLARE r record; BEGIN
          FOR r IN {CHILDREN} LOOP
            EXECUTE format('ALTER TABLE %I DROP CONSTRAINT IF EXISTS %I', r.relname,
                           r.relname || '_geom_polygonal');
          END LOOP;
        END $$
        """
    )
    op.execute(f"ALTER TABLE plan_cells ADD CONSTRAINT plan_cells_geom_polygonal {SHAPE}")


def upgrade() -> None:
    op.execute(
        "ALTER TABLE job_events DROP CONSTRAINT job_events_job_id_fkey,"
        " DROP CONSTRAINT job_events_by_machine_id_fkey, ADD COLUMN machine_id integer"
    )
    op.execute(
        "UPDATE job_events e SET machine_id = j.machine_id FROM jobs j WHERE j.id = e.job_id"
    )
    op.execute("ALTER TABLE job_cell_records DROP CONSTRAINT job_cell_records_job_id_fkey")
    op.execute("ALTER TABLE job_cells_applied DROP CONSTRAINT job_cells_applied_machine_job_fkey")
    op.execute(
        "ALTER TABLE jobs DROP CONSTRAINT uq_jobs_machine_id_id, DROP CONSTRAINT jobs_pkey,"
        " ADD CONSTRAINT jobs_pkey PRIMARY KEY (machine_id, id),"
        " DROP CONSTRAINT jobs_plan_id_fkey, DROP CONSTRAINT jobs_prescription_id_fkey"
    )
    op.execute("CREATE INDEX ix_jobs_id ON jobs (id)")
    op.execute(
        "ALTER TABLE job_cells_applied ADD CONSTRAINT job_cells_applied_machine_job_fkey"
        " FOREIGN KEY (machine_id, job_id) REFERENCES jobs (machine_id, id) ON DELETE CASCADE"
    )
    op.execute(
        "ALTER TABLE job_cell_records ADD CONSTRAINT job_cell_records_machine_job_fkey"
        " FOREIGN KEY (machine_id, job_id) REFERENCES jobs (machine_id, id) ON DELETE CASCADE"
    )
    op.execute(
        "ALTER TABLE job_events ALTER COLUMN machine_id SET NOT NULL,"
        " DROP CONSTRAINT job_events_pkey, ADD CONSTRAINT job_events_pkey PRIMARY KEY"
        " (machine_id, id), ADD CONSTRAINT job_events_machine_job_fkey FOREIGN KEY"
        " (machine_id, job_id) REFERENCES jobs (machine_id, id) ON DELETE CASCADE"
    )
    op.execute(
        "ALTER TABLE alerts DROP CONSTRAINT alerts_pkey,"
        " ADD CONSTRAINT alerts_pkey PRIMARY KEY (machine_id, id)"
    )
    op.execute("CREATE INDEX ix_alerts_id ON alerts (id)")
    op.execute("ALTER TABLE api_tokens DROP CONSTRAINT api_tokens_machine_id_fkey")
    op.execute("ALTER TABLE prescriptions DROP CONSTRAINT prescriptions_machine_id_fkey")
    _plan_cells_up()


def downgrade() -> None:
    _plan_cells_down()
    # rows the application left pointing nowhere would block the keys: drop their links
    op.execute(
        "UPDATE prescriptions r SET machine_id = NULL WHERE machine_id IS NOT NULL"
        " AND NOT EXISTS (SELECT 1 FROM machines m WHERE m.id = r.machine_id)"
    )
    op.execute(
        "DELETE FROM api_tokens t WHERE machine_id IS NOT NULL"
        " AND NOT EXISTS (SELECT 1 FROM machines m WHERE m.id = t.machine_id)"
    )
    op.execute(
        "UPDATE job_events e SET by_machine_id = NULL WHERE by_machine_id IS NOT NULL"
        " AND NOT EXISTS (SELECT 1 FROM machines m WHERE m.id = e.by_machine_id)"
    )
    op.execute(
        "ALTER TABLE prescriptions ADD CONSTRAINT prescriptions_machine_id_fkey"
        " FOREIGN KEY (machine_id) REFERENCES machines (id) ON DELETE SET NULL"
    )
    op.execute(
        "ALTER TABLE api_tokens ADD CONSTRAINT api_tokens_machine_id_fkey"
        " FOREIGN KEY (machine_id) REFERENCES machines (id) ON DELETE CASCADE"
    )
    op.execute("DROP INDEX ix_alerts_id")
    op.execute(
        "ALTER TABLE alerts DROP CONSTRAINT alerts_pkey, ADD CONSTRAINT alerts_pkey PRIMARY KEY (id)"
    )
    op.execute(
        "ALTER TABLE job_events DROP CONSTRAINT job_events_machine_job_fkey,"
        " DROP CONSTRAINT job_events_pkey, ADD CONSTRAINT job_events_pkey PRIMARY KEY (id),"
        " DROP COLUMN machine_id"
    )
    op.execute("ALTER TABLE job_cell_records DROP CONSTRAINT job_cell_records_machine_job_fkey")
    op.execute("ALTER TABLE job_cells_applied DROP CONSTRAINT job_cells_applied_machine_job_fkey")
    op.execute("DROP INDEX ix_jobs_id")
    op.execute(
        "ALTER TABLE jobs DROP CONSTRAINT jobs_pkey, ADD CONSTRAINT jobs_pkey PRIMARY KEY (id),"
        " ADD CONSTRAINT uq_jobs_machine_id_id UNIQUE (machine_id, id),"
        " ADD CONSTRAINT jobs_plan_id_fkey FOREIGN KEY (plan_id) REFERENCES plans (id)"
        "  ON DELETE CASCADE,"
        " ADD CONSTRAINT jobs_prescription_id_fkey FOREIGN KEY (prescription_id)"
        "  REFERENCES prescriptions (id) ON DELETE CASCADE"
    )
    op.execute(
        "ALTER TABLE job_cells_applied ADD CONSTRAINT job_cells_applied_machine_job_fkey"
        " FOREIGN KEY (machine_id, job_id) REFERENCES jobs (machine_id, id)"
        " ON DELETE CASCADE ON UPDATE CASCADE"
    )
    op.execute(
        "ALTER TABLE job_cell_records ADD CONSTRAINT job_cell_records_job_id_fkey"
        " FOREIGN KEY (job_id) REFERENCES jobs (id) ON DELETE CASCADE"
    )
    op.execute(
        "ALTER TABLE job_events ADD CONSTRAINT job_events_job_id_fkey FOREIGN KEY (job_id)"
        " REFERENCES jobs (id) ON DELETE CASCADE,"
        " ADD CONSTRAINT job_events_by_machine_id_fkey FOREIGN KEY (by_machine_id)"
        " REFERENCES machines (id) ON DELETE SET NULL"
    )
