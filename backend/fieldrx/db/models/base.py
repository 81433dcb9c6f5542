"""What every model shares: the declarative base, the creation-time column, and the
mapper arguments of the tables keyed by machine.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import DateTime, func
from sqlalchemy.orm import DeclarativeBase, mapped_column


def now_column() -> Any:
    """A timestamp column the database sets to the time of the insert."""
    return mapped_column(DateTime(timezone=True), server_default=func.now(), nullable=False)


class Base(DeclarativeBase):
    pass


# Mapper arguments of the machine-keyed tables whose mapper key is ``id`` alone (the
# database's is (machine_id, id), migration 0017): the ORM's UPDATE and DELETE then say
# ``WHERE id = ? AND machine_id = ?``. Past one node (Citus) a statement naming the
# distribution column is a router plan on one shard; by ``id`` alone it runs on every shard.
# SQLAlchemy adds a "version" column to those WHERE clauses; with no generator the
# application sets the value (a row's machine never changes), so nothing else is written.
def machine_routed(machine_id: Any) -> dict[str, Any]:
    return {"version_id_col": machine_id, "version_id_generator": False}
