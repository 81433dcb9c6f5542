"""telemetry partitioned by record time, one partition per UTC day, managed by pg_partman.

Why: telemetry was one table with no retention; 200 machines at 10 Hz for
10 h/day is 72 million rows a day. Declarative RANGE partitioning on ``t`` (daily) keeps
each day's indexes small, lets a query that names a time range touch only its days, and
makes retention a ``DROP TABLE`` of whole days instead of a DELETE.

* ``telemetry`` becomes ``PARTITION BY RANGE (t)``. The primary key of a partitioned table
  must hold the partition key, so it is (machine_id, stream, seq, t); ingest still
  deduplicates by (machine_id, stream, seq) under its per-machine advisory lock
  (``fieldrx.fleet.ingest``), now with lookups bounded in time (below).
* Every partition gets the parent's indexes: btree (machine_id, t), btree
  (job_id, cell_seq), BRIN (t) and the GiST on geom.
* pg_partman (Debian's ``postgresql-15-partman``, the v4 API; v5 also works) creates the
  days ahead (premake 4) and drops days past the retention; ``infinite_time_partitions``
  keeps premaking through quiet weeks. A default partition catches a record whose day has
  no partition yet; ``fieldrx telemetry-maintenance`` (also run by ``fieldrx worker``)
  moves such rows into their day (``fieldrx.fleet.partitions``).
* ``telemetry_streams.max_seq``: the highest seq stored on the stream. With it (and the
  stream's first_t / last_t) ingest knows when a batch cannot hold a stored seq and skips
  the lookup, and bounds the lookups it needs to the stream's days.
* ``telemetry_job_spans``: per (machine, job) the first and last record time, so a job's
  queries (report, as-applied points, exports) name a time range and touch only the job's
  days (an unbounded query plans every partition: ~50 ms at 400 days, measured).

Existing rows are kept: the old table is renamed, partitions are created for every day
that holds data, the rows are copied with INSERT .. SELECT and the old table is dropped.
The downgrade does the reverse.

Revision ID: 0010_telemetry_partitions
Revises: 0009_job_kinds
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0010_telemetry_partitions"
down_revision: str | Sequence[str] | None = "0009_job_kinds"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

PREMAKE = 4
INDEXES = (
    ("ix_telemetry_machine_t", "btree (machine_id, t)"),
    ("ix_telemetry_job_cell", "btree (job_id, cell_seq)"),
    ("idx_telemetry_geom", "gist (geom)"),
)


def _partman_schema() -> str:
    """Create pg_partman (schema ``partman``) when missing; its schema. The extension is
    not trusted: ``fieldrx.db.bootstrap.ensure_database`` creates it as the superuser, as
    it does PostGIS; here it is only created when the migrating user may."""
    bind = op.get_bind()
    row = bind.execute(
        sa.text(
            "SELECT extnamespace::regnamespace::text FROM pg_extension WHERE extname = 'pg_partman'"
        )
    ).first()
    if row is not None:
        return str(row[0])
    if (
        bind.execute(
            sa.text("SELECT 1 FROM pg_available_extensions WHERE name = 'pg_partman'")
        ).first()
        is None
    ):
        raise RuntimeError(
            "pg_partman is not installed on the database server: run scripts/setup.sh or"
            " apt-get install postgresql-15-partman (telemetry is partitioned by day with it)"
        )
    op.execute("CREATE SCHEMA IF NOT EXISTS partman")
    op.execute("CREATE EXTENSION IF NOT EXISTS pg_partman SCHEMA partman")
    return "partman"


def upgrade() -> None:
    pm = _partman_schema()
    op.execute("SET LOCAL timezone = 'UTC'")  # day boundaries at UTC midnight (pg_partman docs)
    op.execute("ALTER TABLE telemetry RENAME TO telemetry_old")
    op.execute("ALTER TABLE telemetry_old RENAME CONSTRAINT telemetry_pkey TO telemetry_old_pkey")
    op.execute(
        "ALTER TABLE telemetry_old RENAME CONSTRAINT telemetry_machine_id_fkey"
        " TO telemetry_old_machine_id_fkey"
    )
    for name, _ in INDEXES:
        op.execute(f"ALTER INDEX {name} RENAME TO {name.replace('telemetry', 'telemetry_old')}")
    # same columns, order, types, defaults and NOT NULLs as the old table
    op.execute(
        "CREATE TABLE telemetry (LIKE telemetry_old INCLUDING DEFAULTS INCLUDING CONSTRAINTS,"
        " CONSTRAINT telemetry_pkey PRIMARY KEY (machine_id, stream, seq, t),"
        " CONSTRAINT telemetry_machine_id_fkey FOREIGN KEY (machine_id)"
        " REFERENCES machines (id) ON DELETE CASCADE) PARTITION BY RANGE (t)"
    )
    for name, how in INDEXES:
        op.execute(f"CREATE INDEX {name} ON telemetry USING {how}")
    op.execute("CREATE INDEX ix_telemetry_t_brin ON telemetry USING brin (t)")
    version = (
        op.get_bind()
        .execute(sa.text("SELECT extversion FROM pg_extension WHERE extname = 'pg_partman'"))
        .scalar_one()
    )
    v4 = int(str(version).split(".")[0]) < 5  # Debian 12: 4.7; PGDG images: 5 (renamed args)
    kind = "native" if v4 else "range"
    analyze = ", p_analyze := false" if v4 else ""
    op.execute(
        f"SELECT {pm}.create_parent(p_parent_table := 'public.telemetry', p_control := 't',"
        f" p_type := '{kind}', p_interval := '1 day', p_premake := {PREMAKE},"
        " p_jobmon := false)"
    )
    op.execute(
        f"UPDATE {pm}.part_config SET infinite_time_partitions = true, retention = NULL,"
        " retention_keep_table = false WHERE parent_table = 'public.telemetry'"
    )
    # a partition for every day that holds rows, then the rows themselves
    op.execute(
        f"SELECT {pm}.create_partition_time('public.telemetry', array_agg(d){analyze})"
        " FROM (SELECT DISTINCT date_trunc('day', t) AS d FROM telemetry_old) days"
        " HAVING count(*) > 0"
    )
    op.execute("INSERT INTO telemetry SELECT * FROM telemetry_old")
    op.execute("DROP TABLE telemetry_old")

    op.add_column("telemetry_streams", sa.Column("max_seq", sa.BigInteger(), nullable=True))
    # the stream's bounds must hold every stored record: recomputed from the rows
    op.execute(
        "UPDATE telemetry_streams ts SET max_seq = s.mx, first_t = least(ts.first_t, s.t0),"
        " last_t = greatest(ts.last_t, s.t1)"
        " FROM (SELECT machine_id, stream, max(seq) AS mx, min(t) AS t0, max(t) AS t1"
        "       FROM telemetry GROUP BY machine_id, stream) s"
        " WHERE ts.machine_id = s.machine_id AND ts.stream = s.stream"
    )
    op.create_table(
        "telemetry_job_spans",
        sa.Column(
            "machine_id",
            sa.Integer(),
            sa.ForeignKey("machines.id", ondelete="CASCADE"),
            primary_key=True,
        ),
        sa.Column("job_id", sa.Integer(), primary_key=True),
        sa.Column("first_t", sa.DateTime(timezone=True), nullable=False),
        sa.Column("last_t", sa.DateTime(timezone=True), nullable=False),
        sa.Column("n_records", sa.BigInteger(), nullable=False),
    )
    op.execute(
        "INSERT INTO telemetry_job_spans (machine_id, job_id, first_t, last_t, n_records)"
        " SELECT machine_id, job_id, min(t), max(t), count(*) FROM telemetry"
        " WHERE job_id IS NOT NULL GROUP BY machine_id, job_id"
    )


def downgrade() -> None:
    pm = (
        op.get_bind()
        .execute(
            sa.text(
                "SELECT extnamespace::regnamespace::text FROM pg_extension WHERE extname = 'pg_partman'"
            )
        )
        .scalar_one()
    )
    op.drop_table("telemetry_job_spans")
    op.drop_column("telemetry_streams", "max_seq")
    op.execute(f"DELETE FROM {pm}.part_config WHERE parent_table = 'public.telemetry'")
    op.execute(f"DROP TABLE IF EXISTS {pm}.template_public_telemetry")
    op.execute("ALTER TABLE telemetry RENAME TO telemetry_part")
    op.execute("ALTER TABLE telemetry_part RENAME CONSTRAINT telemetry_pkey TO telemetry_part_pkey")
    op.execute(
        "ALTER TABLE telemetry_part RENAME CONSTRAINT telemetry_machine_id_fkey"
        " TO telemetry_part_machine_id_fkey"
    )
    for name, _ in (*INDEXES, ("ix_telemetry_t_brin", "")):
        op.execute(f"ALTER INDEX {name} RENAME TO {name.replace('telemetry', 'telemetry_part')}")
    op.execute(
        "CREATE TABLE telemetry (LIKE telemetry_part INCLUDING DEFAULTS INCLUDING CONSTRAINTS,"
        " CONSTRAINT telemetry_pkey PRIMARY KEY (machine_id, stream, seq),"
        " CONSTRAINT telemetry_machine_id_fkey FOREIGN KEY (machine_id)"
        " REFERENCES machines (id) ON DELETE CASCADE)"
    )
    op.execute("INSERT INTO telemetry SELECT * FROM telemetry_part")
    for name, how in INDEXES:
        op.execute(f"CREATE INDEX {name} ON telemetry USING {how}")
    op.execute("DROP TABLE telemetry_part")  # with its partitions
