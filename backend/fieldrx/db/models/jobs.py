"""Jobs: a prescription version or a plan bound to a machine, its state changes, what
was applied per cell, and the archive that outlives it.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from sqlalchemy import (
    ARRAY,
    BigInteger,
    Boolean,
    CheckConstraint,
    DateTime,
    Double,
    ForeignKey,
    ForeignKeyConstraint,
    Index,
    Integer,
    String,
    Text,
    func,
    text,
)
from sqlalchemy.dialects.postgresql import JSONB
from sqlalchemy.orm import Mapped, mapped_column

from fieldrx.db.models.base import Base, machine_routed, now_column
from fieldrx.db.models.kinds import job_kind_check

JOB_STATES = ("planned", "sent", "downloaded", "running", "paused", "completed", "aborted")


class Job(Base):
    __tablename__ = "jobs"
    __table_args__ = (
        CheckConstraint(f"state IN {JOB_STATES}", name="ck_job_state"),
        job_kind_check(),
        CheckConstraint(
            "(kind = 'prescription_map' AND prescription_id IS NOT NULL"
            " AND prescription_version IS NOT NULL)"
            " OR (kind <> 'prescription_map' AND plan_id IS NOT NULL)",
            name="ck_job_source",
        ),
        # the key is (machine_id, id) (migration 0017: Citus's keys hold the distribution
        # column); the mapper keeps ``id`` (globally unique from its sequence) for lookups
        Index("ix_jobs_id", "id"),
    )
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    # null for the sensor kinds, which drive a plan's path with sensor-decided rates
    # no foreign keys to the coordinator's prescriptions / plans (migration 0017): their
    # deletes delete the jobs (fieldrx.services.evidence.delete_jobs)
    prescription_id: Mapped[int | None] = mapped_column(Integer)
    prescription_version: Mapped[int | None] = mapped_column(Integer)
    kind: Mapped[str] = mapped_column(
        String(32), default="prescription_map", server_default="prescription_map"
    )
    settings: Mapped[dict[str, Any]] = mapped_column(
        JSONB, default=dict, server_default=text("'{}'")
    )
    plan_id: Mapped[int | None] = mapped_column(Integer)
    machine_id: Mapped[int] = mapped_column(
        ForeignKey("machines.id", ondelete="CASCADE"), index=True
    )
    name: Mapped[str] = mapped_column(String(200), default="")
    state: Mapped[str] = mapped_column(String(20), default="planned")
    n_cells: Mapped[int] = mapped_column(Integer, default=0)
    cells_applied: Mapped[int] = mapped_column(Integer, default=0)
    package_checksum: Mapped[str] = mapped_column(String(64), default="")
    # cells flagged no data / outside the meter range when the job was made, and whether
    # the sender confirmed sending them anyway (created_by is who confirmed)
    flagged_cells: Mapped[int] = mapped_column(Integer, default=0, server_default="0")
    flagged_confirmed: Mapped[bool] = mapped_column(Boolean, default=False, server_default="false")
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    created_at: Mapped[dt.datetime] = now_column()
    updated_at: Mapped[dt.datetime] = now_column()

    __mapper_args__ = machine_routed(machine_id)


class JobEvent(Base):
    """Who moved a job to which state, and when."""

    __tablename__ = "job_events"
    # co-located with its job: keyed (machine_id, id) in the database, the job referenced by
    # (machine_id, job_id) (migration 0017)
    __table_args__ = (
        ForeignKeyConstraint(
            ["machine_id", "job_id"],
            ["jobs.machine_id", "jobs.id"],
            name="job_events_machine_job_fkey",
            ondelete="CASCADE",
        ),
    )
    id: Mapped[int] = mapped_column(primary_key=True)
    machine_id: Mapped[int] = mapped_column(Integer)
    job_id: Mapped[int] = mapped_column(Integer, index=True)
    state: Mapped[str] = mapped_column(String(20))
    by_user_id: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    by_machine_id: Mapped[int | None] = mapped_column(Integer)  # the job's machine
    note: Mapped[str] = mapped_column(Text, default="")
    at: Mapped[dt.datetime] = now_column()


class JobCellApplied(Base):
    """Per-cell as-applied aggregate of a job, kept up to date by telemetry ingest.
    Keyed by machine first (the distribution column, migration 0014_machine_keys)."""

    __tablename__ = "job_cells_applied"
    __table_args__ = (
        ForeignKeyConstraint(
            ["machine_id", "job_id"],
            ["jobs.machine_id", "jobs.id"],
            name="job_cells_applied_machine_job_fkey",
            ondelete="CASCADE",
        ),
    )
    machine_id: Mapped[int] = mapped_column(Integer, primary_key=True)
    job_id: Mapped[int] = mapped_column(Integer, primary_key=True)
    seq: Mapped[int] = mapped_column(Integer, primary_key=True)
    n_records: Mapped[int] = mapped_column(Integer, default=0)
    target_rate_sum: Mapped[float] = mapped_column(Double, default=0.0)
    applied_rate_sum: Mapped[float] = mapped_column(Double, default=0.0)
    first_t: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))
    last_t: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))


class JobCellRecord(Base):
    """Uplink profile ``thin``: one cell's as-applied figures as the tractor computed them
    (``fieldrx_edge.cell_records.CellRecord``), kept forever (migration 0011). Deduplicated by
    (machine, stream, seq) like telemetry; a thin job's report sums them per cell."""

    __tablename__ = "job_cell_records"
    __table_args__ = (
        Index("ix_job_cell_records_job_cell", "job_id", "cell_seq"),
        ForeignKeyConstraint(
            ["machine_id", "job_id"],
            ["jobs.machine_id", "jobs.id"],
            name="job_cell_records_machine_job_fkey",
            ondelete="CASCADE",
        ),
    )
    machine_id: Mapped[int] = mapped_column(
        ForeignKey("machines.id", ondelete="CASCADE"), primary_key=True
    )
    stream: Mapped[str] = mapped_column(String(32), primary_key=True)
    seq: Mapped[int] = mapped_column(BigInteger, primary_key=True)
    job_id: Mapped[int] = mapped_column(Integer)
    cell_seq: Mapped[int | None] = mapped_column(Integer)
    t_entry: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True))
    t_exit: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True))
    n_fixes: Mapped[int] = mapped_column(Integer)
    worked_s: Mapped[float] = mapped_column(Double)
    mass_g: Mapped[float] = mapped_column(Double)
    driven_m: Mapped[float | None] = mapped_column(Double)
    mean_speed_m_s: Mapped[float | None] = mapped_column(Double)
    mean_target_rate_kg_ha: Mapped[float | None] = mapped_column(Double)
    mean_applied_rate_kg_ha: Mapped[float | None] = mapped_column(Double)
    flags: Mapped[list[str]] = mapped_column(ARRAY(String(32)), server_default="{}")
    received_at: Mapped[dt.datetime] = mapped_column(
        DateTime(timezone=True), server_default=func.now()
    )


class CellRecordStream(Base):
    """A thin agent's cell-record stream: its acknowledged seq (``TelemetryStream`` for
    cell records; migration 0011)."""

    __tablename__ = "cell_record_streams"
    machine_id: Mapped[int] = mapped_column(
        ForeignKey("machines.id", ondelete="CASCADE"), primary_key=True
    )
    stream: Mapped[str] = mapped_column(String(32), primary_key=True)
    first_seq: Mapped[int] = mapped_column(BigInteger)
    acked_seq: Mapped[int] = mapped_column(BigInteger)
    n_records: Mapped[int] = mapped_column(BigInteger)
    first_seen_at: Mapped[dt.datetime] = mapped_column(
        DateTime(timezone=True), server_default=func.now()
    )
    last_seen_at: Mapped[dt.datetime] = mapped_column(
        DateTime(timezone=True), server_default=func.now()
    )


class JobArchive(Base):
    """A job's as-applied evidence kept after its machine, field, plan or prescription is
    deleted (migration 0007): no foreign key to any of them, only to the organisation."""

    __tablename__ = "job_archives"
    job_id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    name: Mapped[str] = mapped_column(String(200), default="", server_default="")
    archived_at: Mapped[dt.datetime] = now_column()
    archived_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    summary: Mapped[dict[str, Any]] = mapped_column(JSONB)
    cells: Mapped[dict[str, Any]] = mapped_column(JSONB)
