"""The kinds of jobs as rows: ``jobs.kind`` is a foreign key to ``job_kinds``, whose rows
are the job-kind registry's (``fieldrx_edge.jobkinds.registry``), written by every
``fieldrx migrate`` (``db.kinds.sync_job_kinds``, migration 0019), so the database admits
exactly the kinds the code registers without a migration per kind. (Task kinds are the
same pattern: ``tasks.kinds`` and the ``task_kinds`` rows.)
"""

from __future__ import annotations

from sqlalchemy import CheckConstraint, String
from sqlalchemy.orm import Mapped, mapped_column

from fieldrx.db.models.base import Base


class JobKindRow(Base):
    """A job kind of the registry; a reference table past one node (Citus), so the jobs'
    foreign key holds on every shard."""

    __tablename__ = "job_kinds"
    __table_args__ = (
        CheckConstraint("rates_from IN ('cells', 'sensors')", name="ck_job_kinds_rates_from"),
    )
    name: Mapped[str] = mapped_column(String(32), primary_key=True)
    rates_from: Mapped[str] = mapped_column(String(16))
