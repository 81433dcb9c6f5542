"""Database bootstrap: create the database, PostGIS and pg_partman if missing, then migrate.

Neither PostGIS nor pg_partman is a trusted extension, so they are created by a
superuser connection (docs/architecture.md, "Stack notes"); migrations then run as the
application user.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import psycopg
from alembic.config import Config
from geoalchemy2 import alembic_helpers
from psycopg import sql
from sqlalchemy.engine import make_url

from fieldrx.settings import get_settings


def _root() -> Path:
    """Folder holding alembic.ini: the checkout in development, FIELDRX_ROOT or cwd in an image."""
    for candidate in (
        os.environ.get("FIELDRX_ROOT"),
        Path(__file__).resolve().parents[3],
        Path.cwd(),
    ):
        if candidate and (Path(candidate) / "alembic.ini").is_file():
            return Path(candidate)
    raise FileNotFoundError("alembic.ini not found: set FIELDRX_ROOT to the folder that holds it")


def alembic_config(url: str | None = None) -> Config:
    root = _root()
    cfg = Config(str(root / "alembic.ini"))
    cfg.set_main_option("script_location", str(root / "migrations"))
    cfg.set_main_option("sqlalchemy.url", (url or get_settings().database_url).replace("%", "%%"))
    return cfg


# partitions are made at run time (plan_cells per plan, telemetry per day by pg_partman):
# no model names them, so schema comparison must not take them for tables to drop
_PARTITION = re.compile(r"^(plan_cells_p\d+|telemetry_p\d{4}_\d{2}_\d{2}|telemetry_default)$")


def include_object(
    obj: Any, name: str | None, type_: str, reflected: bool, compare_to: Any
) -> bool:
    """Alembic ``include_object``: GeoAlchemy2's rules (PostGIS's own tables and spatial
    indexes); run-time partitions left out; procrastinate's queue tables left out too
    (revision 0012 creates them from the SQL procrastinate ships, not from models)."""
    if type_ == "table" and reflected and name is not None and _PARTITION.match(name):
        return False
    if type_ == "table" and (name or "").startswith("procrastinate_"):
        return False
    table = getattr(obj, "table", None)
    if table is not None and str(getattr(table, "name", "")).startswith("procrastinate_"):
        return False
    return bool(alembic_helpers.include_object(obj, name, type_, reflected, compare_to))


def ensure_database(url: str | None = None, superuser_dsn: str | None = None) -> None:
    """Create the database named in ``url`` and the postgis and pg_partman (schema
    ``partman``, when the server has it; migration 0010 says how to install it) extensions
    in it when missing."""
    u = make_url(url or get_settings().database_url)
    if not u.database:
        raise ValueError(f"{u.render_as_string()}: the URL names no database")
    admin = superuser_dsn or (
        f"postgresql://{u.username or 'postgres'}@{u.host or '127.0.0.1'}:{u.port or 5432}/postgres"
    )
    with psycopg.connect(admin, autocommit=True) as conn:
        exists = conn.execute(
            "SELECT 1 FROM pg_database WHERE datname = %s", (u.database,)
        ).fetchone()
        if not exists:
            conn.execute(sql.SQL("CREATE DATABASE {}").format(sql.Identifier(u.database)))
    target = admin.rsplit("/", 1)[0] + f"/{u.database}"
    with psycopg.connect(target, autocommit=True) as conn:
        conn.execute("CREATE EXTENSION IF NOT EXISTS postgis")
        available = conn.execute(
            "SELECT installed_version IS NULL FROM pg_available_extensions"
            " WHERE name = 'pg_partman'"
        ).fetchone()
        if available is not None and available[0]:
            conn.execute("CREATE SCHEMA IF NOT EXISTS partman")
            conn.execute("CREATE EXTENSION IF NOT EXISTS pg_partman SCHEMA partman")


def drop_database(url: str, superuser_dsn: str | None = None) -> None:
    u = make_url(url)
    if not u.database:
        raise ValueError(f"{u.render_as_string()}: the URL names no database")
    admin = superuser_dsn or (
        f"postgresql://{u.username or 'postgres'}@{u.host or '127.0.0.1'}:{u.port or 5432}/postgres"
    )
    with psycopg.connect(admin, autocommit=True) as conn:
        conn.execute(
            sql.SQL("DROP DATABASE IF EXISTS {} WITH (FORCE)").format(sql.Identifier(u.database))
        )
