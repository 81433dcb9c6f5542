"""What the machines send and what follows from it: telemetry rows and streams, the
job spans of a machine's telemetry, live machine status and alerts.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from geoalchemy2 import Geometry
from sqlalchemy import (
    ARRAY,
    BigInteger,
    Boolean,
    DateTime,
    Double,
    ForeignKey,
    Index,
    Integer,
    SmallInteger,
    String,
    Text,
    func,
)
from sqlalchemy.orm import Mapped, mapped_column

from fieldrx.db.models.base import Base, machine_routed, now_column


class Telemetry(Base):
    """One record per fix. (machine_id, stream, seq) is the deduplication key (stream ''
    is the legacy stream of agents that send none); rows arrive by COPY.

    Partitioned by record time, one partition per UTC day, managed by pg_partman
    (migration 0010, ``fieldrx.fleet.partitions``): the primary key must hold ``t``,
    ingest keeps (machine_id, stream, seq) unique under its per-machine lock. Every
    query names a machine or a job (the distribution key of a Citus deployment,
    docs/scale.md) and, where it can, a time range (partition pruning).
    """

    __tablename__ = "telemetry"
    __table_args__ = (
        Index("ix_telemetry_machine_t", "machine_id", "t"),
        Index("ix_telemetry_job_cell", "job_id", "cell_seq"),
        Index("ix_telemetry_t_brin", "t", postgresql_using="brin"),
        {"postgresql_partition_by": "RANGE (t)"},
    )
    machine_id: Mapped[int] = mapped_column(
        ForeignKey("machines.id", ondelete="CASCADE"), primary_key=True
    )
    stream: Mapped[str] = mapped_column(String(32), primary_key=True, server_default="")
    seq: Mapped[int] = mapped_column(BigInteger, primary_key=True)
    t: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True), primary_key=True)
    fix_period_s: Mapped[float | None] = mapped_column(Double)
    received_at: Mapped[dt.datetime] = mapped_column(
        DateTime(timezone=True), server_default=func.now()
    )
    job_id: Mapped[int | None] = mapped_column(Integer)
    # null when the record has no position (fix lost): the protocol allows lon/lat null
    geom: Mapped[Any | None] = mapped_column(
        Geometry("POINT", srid=4326, spatial_index=True), nullable=True
    )
    fix_quality: Mapped[int] = mapped_column(SmallInteger, default=0)
    hdop: Mapped[float | None] = mapped_column(Double)
    speed_raw_m_s: Mapped[float | None] = mapped_column(Double)
    speed_filtered_m_s: Mapped[float | None] = mapped_column(Double)
    heading_deg: Mapped[float | None] = mapped_column(Double)
    cell_seq: Mapped[int | None] = mapped_column(Integer)
    target_rate_kg_ha: Mapped[float | None] = mapped_column(Double)
    applied_rate_kg_ha: Mapped[float | None] = mapped_column(Double)
    target_shaft_rpm: Mapped[float | None] = mapped_column(Double)
    actual_shaft_rpm: Mapped[float | None] = mapped_column(Double)
    duty: Mapped[float | None] = mapped_column(Double)
    ndvi: Mapped[float | None] = mapped_column(Double)
    depth_mm: Mapped[float | None] = mapped_column(Double)
    implement_down: Mapped[bool] = mapped_column(Boolean, default=False)
    alarms: Mapped[list[str]] = mapped_column(ARRAY(String(32)), default=list)
    queue_backlog: Mapped[int] = mapped_column(Integer, default=0)
    # sensor job kinds: raw NDVI, actuator position, controller gains in force
    ndvi_raw: Mapped[float | None] = mapped_column(Double)
    actuator_mm: Mapped[float | None] = mapped_column(Double)
    gain_kp: Mapped[float | None] = mapped_column(Double)
    gain_ki: Mapped[float | None] = mapped_column(Double)
    gain_kd: Mapped[float | None] = mapped_column(Double)


class TelemetryStream(Base):
    """One agent queue's numbering of a machine's records (telemetry format 2): its
    acknowledged seq and what the fleet view shows about it (migration 0004)."""

    __tablename__ = "telemetry_streams"
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
    first_t: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))
    last_t: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))
    # highest seq stored on the stream (null: none): ingest skips the dedup lookup for a
    # batch above it and bounds its lookups by first_t..last_t (migration 0010)
    max_seq: Mapped[int | None] = mapped_column(BigInteger)


class TelemetryJobSpan(Base):
    """First and last record time of a machine's records of one job: a job's telemetry
    queries name this range, so they touch only the job's daily partitions (0010)."""

    __tablename__ = "telemetry_job_spans"
    machine_id: Mapped[int] = mapped_column(
        ForeignKey("machines.id", ondelete="CASCADE"), primary_key=True
    )
    job_id: Mapped[int] = mapped_column(Integer, primary_key=True)
    first_t: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True))
    last_t: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True))
    n_records: Mapped[int] = mapped_column(BigInteger)


class MachineStatus(Base):
    """Latest state of a machine, upserted by ingest; online = seen within the heartbeat timeout."""

    __tablename__ = "machine_status"
    machine_id: Mapped[int] = mapped_column(
        ForeignKey("machines.id", ondelete="CASCADE"), primary_key=True
    )
    last_seen_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))
    last_t: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))
    acked_seq: Mapped[int] = mapped_column(BigInteger, default=0)
    lon: Mapped[float | None] = mapped_column(Double)
    lat: Mapped[float | None] = mapped_column(Double)
    speed_m_s: Mapped[float | None] = mapped_column(Double)
    heading_deg: Mapped[float | None] = mapped_column(Double)
    job_id: Mapped[int | None] = mapped_column(Integer)
    cell_seq: Mapped[int | None] = mapped_column(Integer)
    target_rate_kg_ha: Mapped[float | None] = mapped_column(Double)
    applied_rate_kg_ha: Mapped[float | None] = mapped_column(Double)
    queue_backlog: Mapped[int] = mapped_column(Integer, default=0)
    alarms: Mapped[list[str]] = mapped_column(ARRAY(String(32)), default=list)
    # when "offline" was announced on the live socket (fleet.status.sweep_offline)
    offline_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))


class Alert(Base):
    __tablename__ = "alerts"
    # keyed (machine_id, id) in the database (migration 0017); ``id`` stays the mapper's key
    __table_args__ = (Index("ix_alerts_job_kind", "job_id", "kind"), Index("ix_alerts_id", "id"))
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    machine_id: Mapped[int] = mapped_column(
        ForeignKey("machines.id", ondelete="CASCADE"), index=True
    )
    job_id: Mapped[int | None] = mapped_column(Integer)
    kind: Mapped[str] = mapped_column(String(32))
    message: Mapped[str] = mapped_column(Text)
    value: Mapped[float | None] = mapped_column(Double)
    started_at: Mapped[dt.datetime] = now_column()
    ended_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))
    acknowledged_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))
    acknowledged_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))

    __mapper_args__ = machine_routed(machine_id)
