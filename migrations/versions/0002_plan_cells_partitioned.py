"""plan_cells partitioned by plan (LIST on plan_id), one partition per plan.

Why: storing a 1,000 ha plan (~870k cells) into one shared table spent ~20 s
maintaining the GiST and primary-key indexes row by row (raw COPY of the same
rows: under 1 s). With one partition per plan, fieldrx.services.plans COPYs the
cells into a fresh table, builds its indexes in bulk and attaches it; deleting
a plan drops its partition instead of deleting rows one by one.

Triggers keep it transparent for everything else:
* AFTER INSERT ON plans creates the plan's (empty, indexed) partition, unless
  the inserting transaction set ``fieldrx.bulk_plan_cells = on`` because it
  attaches a bulk-built partition itself;
* BEFORE DELETE ON plans drops the plan's partition (also on cascades from
  fields / organisations).
Columns, index and constraint names of plan_cells are unchanged.

Revision ID: 0002_plan_cells_partitioned
Revises: 0001
"""

from __future__ import annotations

from collections.abc import Sequence

from alembic import op

revision: str = "0002_plan_cells_partitioned"
down_revision: str | Sequence[str] | None = "0001"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

COLUMNS = """
    plan_id integer NOT NULL,
    seq integer NOT NULL,
    swath integer NOT NULL,
    index_in_swath integer NOT NULL,
    area_m2 double precision NOT NULL,
    corners_utm double precision[] NOT NULL,
    geom geometry(POLYGON, 4326) NOT NULL,
    CONSTRAINT plan_cells_pkey PRIMARY KEY (plan_id, seq),
    CONSTRAINT plan_cells_plan_id_fkey FOREIGN KEY (plan_id)
        REFERENCES plans (id) ON DELETE CASCADE
"""
COLS = "plan_id, seq, swath, index_in_swath, area_m2, corners_utm, geom"

FUNCTIONS = """
CREATE FUNCTION fieldrx_plan_cells_partition() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
  IF coalesce(current_setting('fieldrx.bulk_plan_cells', true), '') <> 'on' THEN
    EXECUTE format('CREATE TABLE %I PARTITION OF plan_cells FOR VALUES IN (%s)',
                   'plan_cells_p' || NEW.id, NEW.id);
  END IF;
  RETURN NULL;
END $$;

CREATE FUNCTION fieldrx_plan_cells_drop_partition() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
  EXECUTE format('DROP TABLE IF EXISTS %I', 'plan_cells_p' || OLD.id);
  RETURN OLD;
END $$;

CREATE TRIGGER plans_cells_partition AFTER INSERT ON plans
  FOR EACH ROW EXECUTE FUNCTION fieldrx_plan_cells_partition();
CREATE TRIGGER plans_cells_drop_partition BEFORE DELETE ON plans
  FOR EACH ROW EXECUTE FUNCTION fieldrx_plan_cells_drop_partition();
"""


def _rename_old() -> None:
    op.execute("ALTER TABLE plan_cells RENAME TO plan_cells_old")
    op.execute("ALTER INDEX idx_plan_cells_geom RENAME TO idx_plan_cells_old_geom")
    op.execute(
        "ALTER TABLE plan_cells_old RENAME CONSTRAINT plan_cells_pkey TO plan_cells_old_pkey"
    )
    op.execute(
        "ALTER TABLE plan_cells_old RENAME CONSTRAINT plan_cells_plan_id_fkey "
        "TO plan_cells_old_plan_id_fkey"
    )


def upgrade() -> None:
    _rename_old()
    op.execute(f"CREATE TABLE plan_cells ({COLUMNS}) PARTITION BY LIST (plan_id)")
    op.execute("CREATE INDEX idx_plan_cells_geom ON plan_cells USING gist (geom)")
    op.execute(FUNCTIONS)
    op.execute(
        """
        DO $$
        DECLARE pid integer;
        BEGIN
          FOR pid IN SELECT id FROM plans ORDER BY id LOOP
            EXECUTE format('CREATE TABLE %I PARTITION OF plan_cells FOR VALUES IN (%s)',
                           'plan_cells_p' || pid, pid);
          END LOOP;
        END $$;
        """
    )
    op.execute(f"INSERT INTO plan_cells ({COLS}) SELECT {COLS} FROM plan_cells_old")
    op.execute("DROP TABLE plan_cells_old")


def downgrade() -> None:
    op.execute("DROP TRIGGER plans_cells_partition ON plans")
    op.execute("DROP TRIGGER plans_cells_drop_partition ON plans")
    op.execute("DROP FUNCTION fieldrx_plan_cells_partition()")
    op.execute("DROP FUNCTION fieldrx_plan_cells_drop_partition()")
    _rename_old()
    op.execute(f"CREATE TABLE plan_cells ({COLUMNS})")
    op.execute("CREATE INDEX idx_plan_cells_geom ON plan_cells USING gist (geom)")
    op.execute(f"INSERT INTO plan_cells ({COLS}) SELECT {COLS} FROM plan_cells_old")
    op.execute("DROP TABLE plan_cells_old")  # drops every partition with it
