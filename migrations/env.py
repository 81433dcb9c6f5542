"""Alembic environment: the only way the FieldRx schema changes.

GeoAlchemy2's helpers keep autogenerate from dropping PostGIS's own tables
and from creating spatial indexes twice (docs/architecture.md, "Stack notes"); ``include_object``
also leaves out the partitions made at run time (plan_cells, telemetry).
"""

from __future__ import annotations

from alembic import context
from fieldrx.db.bootstrap import include_object
from fieldrx.db.kinds import sync_job_kinds
from fieldrx.db.models import Base
from fieldrx.settings import get_settings
from geoalchemy2 import alembic_helpers
from sqlalchemy import engine_from_config, pool

config = context.config
target_metadata = Base.metadata


def _url() -> str:
    return config.get_main_option("sqlalchemy.url") or get_settings().database_url


def run_migrations_offline() -> None:
    context.configure(
        url=_url(),
        target_metadata=target_metadata,
        literal_binds=True,
        include_object=include_object,
        process_revision_directives=alembic_helpers.writer,
        render_item=alembic_helpers.render_item,
    )
    with context.begin_transaction():
        context.run_migrations()


def run_migrations_online() -> None:
    connectable = engine_from_config(
        {"sqlalchemy.url": _url()}, prefix="sqlalchemy.", poolclass=pool.NullPool
    )
    with connectable.connect() as connection:
        context.configure(
            connection=connection,
            target_metadata=target_metadata,
            include_object=include_object,
            process_revision_directives=alembic_helpers.writer,
            render_item=alembic_helpers.render_item,
        )
        with context.begin_transaction():
            context.run_migrations()
            # the job kinds' rows are the registry's, whatever revision added the table
            sync_job_kinds(connection)


if context.is_offline_mode():
    run_migrations_offline()
else:
    run_migrations_online()
