"""ORM models: the whole FieldRx schema.

The schema itself changes only through Alembic revisions in ``migrations/``;
these classes describe it for queries. Geometries are stored in WGS84
(SRID 4326) with GiST indexes; metric work happens in the field's UTM zone,
whose EPSG code is stored beside the geometry.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from geoalchemy2 import Geometry
from sqlalchemy import (
    ARRAY,
    BigInteger,
    Boolean,
    CheckConstraint,
    Date,
    DateTime,
    Double,
    ForeignKey,
    ForeignKeyConstraint,
    Index,
    Integer,
    LargeBinary,
    SmallInteger,
    String,
    Text,
    UniqueConstraint,
    func,
    text,
)
from sqlalchemy.dialects.postgresql import JSONB
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship

ROLES = ("admin", "agronomist", "viewer")
JOB_STATES = ("planned", "sent", "downloaded", "running", "paused", "completed", "aborted")
JOB_KINDS = ("prescription_map", "ndvi_topdress", "seeding_depth")  # revision 0009


def _now() -> Any:
    return mapped_column(DateTime(timezone=True), server_default=func.now(), nullable=False)


class Base(DeclarativeBase):
    pass


class Organisation(Base):
    __tablename__ = "organisations"
    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(200), unique=True)
    # plausibility settings: {"ceilings_kg_ha": {crop key or "*": {"N": ...}}, "curve_share_max"}
    agronomy: Mapped[dict[str, Any]] = mapped_column(
        JSONB, default=dict, server_default=text("'{}'::jsonb")
    )
    created_at: Mapped[dt.datetime] = _now()


class User(Base):
    __tablename__ = "users"
    id: Mapped[int] = mapped_column(primary_key=True)
    email: Mapped[str] = mapped_column(String(320), unique=True)
    full_name: Mapped[str] = mapped_column(String(200), default="")
    password_hash: Mapped[str] = mapped_column(String(200))
    is_active: Mapped[bool] = mapped_column(Boolean, default=True, server_default="true")
    created_at: Mapped[dt.datetime] = _now()
    memberships: Mapped[list[Membership]] = relationship(back_populates="user")


class Membership(Base):
    """A user's role in one organisation (a user may belong to several)."""

    __tablename__ = "memberships"
    __table_args__ = (CheckConstraint(f"role IN {ROLES}", name="ck_membership_role"),)
    user_id: Mapped[int] = mapped_column(
        ForeignKey("users.id", ondelete="CASCADE"), primary_key=True
    )
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), primary_key=True
    )
    role: Mapped[str] = mapped_column(String(20))
    user: Mapped[User] = relationship(back_populates="memberships")
    organisation: Mapped[Organisation] = relationship()


class ApiToken(Base):
    """Token kept as an HMAC-SHA256 digest; a user token has a role, a device one a machine"""

    __tablename__ = "api_tokens"
    __table_args__ = (
        CheckConstraint("kind IN ('user', 'device')", name="ck_token_kind"),
        CheckConstraint(
            "(kind = 'user' AND user_id IS NOT NULL AND role IS NOT NULL)"
            " OR (kind = 'device' AND machine_id IS NOT NULL)",
            name="ck_token_owner",
        ),
    )
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    kind: Mapped[str] = mapped_column(String(10))
    user_id: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"))
    # no foreign key: machines are distributed past one node, api_tokens is a reference
    # table (migration 0017); a machine's delete removes its tokens (api/machines.py)
    machine_id: Mapped[int | None] = mapped_column(Integer)
    role: Mapped[str | None] = mapped_column(String(20))
    name: Mapped[str] = mapped_column(String(200), default="")
    token_hash: Mapped[str] = mapped_column(String(64), unique=True)
    prefix: Mapped[str] = mapped_column(String(16))
    created_at: Mapped[dt.datetime] = _now()
    expires_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))
    revoked_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))
    last_used_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))


class Farm(Base):
    __tablename__ = "farms"
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    name: Mapped[str] = mapped_column(String(200))
    notes: Mapped[str] = mapped_column(Text, default="")
    created_at: Mapped[dt.datetime] = _now()


class Field(Base):
    __tablename__ = "fields"
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    farm_id: Mapped[int | None] = mapped_column(ForeignKey("farms.id", ondelete="SET NULL"))
    name: Mapped[str] = mapped_column(String(200))
    crop: Mapped[str] = mapped_column(String(100), default="")
    notes: Mapped[str] = mapped_column(Text, default="")
    boundary: Mapped[Any] = mapped_column(Geometry("MULTIPOLYGON", srid=4326, spatial_index=True))
    utm_epsg: Mapped[int] = mapped_column(Integer)
    area_m2: Mapped[float] = mapped_column(Double)
    # where an import found it ("ISOXML PFD1"): matched again on re-import
    source_ref: Mapped[str] = mapped_column(String(200), default="", server_default="")
    # kept annotations of an import (guidance lines, obstacles ...: GeoJSON features)
    features: Mapped[list[Any]] = mapped_column(
        JSONB, default=list, server_default=text("'[]'::jsonb")
    )
    created_at: Mapped[dt.datetime] = _now()
    updated_at: Mapped[dt.datetime] = _now()


class Machine(Base):
    __tablename__ = "machines"
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    name: Mapped[str] = mapped_column(String(200))
    implement_type: Mapped[str] = mapped_column(String(50), default="spreader")
    width_m: Mapped[float] = mapped_column(Double)
    lag_s: Mapped[float] = mapped_column(Double, default=1.52)
    calibration: Mapped[dict[str, Any]] = mapped_column(JSONB)
    controller: Mapped[dict[str, Any]] = mapped_column(JSONB, default=dict)
    antenna_forward_m: Mapped[float] = mapped_column(Double, default=0.0)
    antenna_lateral_m: Mapped[float] = mapped_column(Double, default=0.0)
    speed_min_m_s: Mapped[float] = mapped_column(Double, default=0.8)
    speed_max_m_s: Mapped[float] = mapped_column(Double, default=2.5)
    # what the implement can do beyond metering: sections, depth actuator, sensors
    capabilities: Mapped[dict[str, Any]] = mapped_column(
        JSONB, default=dict, server_default=text("'{}'::jsonb")
    )
    created_at: Mapped[dt.datetime] = _now()


class Plan(Base):
    """A coverage plan: parameters, metrics and the route; its cells are in ``plan_cells``."""

    __tablename__ = "plans"
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    field_id: Mapped[int] = mapped_column(ForeignKey("fields.id", ondelete="CASCADE"), index=True)
    params: Mapped[dict[str, Any]] = mapped_column(JSONB)
    metrics: Mapped[dict[str, Any]] = mapped_column(JSONB, default=dict)
    heading_deg: Mapped[float] = mapped_column(Double)
    n_cells: Mapped[int] = mapped_column(Integer)
    route: Mapped[Any] = mapped_column(Geometry("LINESTRING", srid=4326, spatial_index=False))
    created_at: Mapped[dt.datetime] = _now()


class PlanCell(Base):
    """One grid cell in path order (seed 001 Table 1): clipped polygon + the 4 UTM corners."""

    __tablename__ = "plan_cells"
    plan_id: Mapped[int] = mapped_column(
        ForeignKey("plans.id", ondelete="CASCADE"), primary_key=True
    )
    seq: Mapped[int] = mapped_column(Integer, primary_key=True)
    swath: Mapped[int] = mapped_column(Integer)
    index_in_swath: Mapped[int] = mapped_column(Integer)
    area_m2: Mapped[float] = mapped_column(Double)
    corners_utm: Mapped[list[float]] = mapped_column(ARRAY(Double))
    geom: Mapped[Any] = mapped_column(
        Geometry("GEOMETRY", srid=4326, spatial_index=True)
    )  # Polygon or MultiPolygon (a split cell stays whole, migration 0013_cells)


class SoilImport(Base):
    """One uploaded soil file: its samples are deleted with it; the same bytes twice are refused."""

    __tablename__ = "soil_imports"
    __table_args__ = (UniqueConstraint("field_id", "sha256", name="uq_soil_imports_field_sha256"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    field_id: Mapped[int] = mapped_column(ForeignKey("fields.id", ondelete="CASCADE"), index=True)
    filename: Mapped[str] = mapped_column(String(255), default="")
    sha256: Mapped[str] = mapped_column(String(71))
    batch: Mapped[str] = mapped_column(String(64), default="")
    n_samples: Mapped[int] = mapped_column(Integer, default=0)
    n_outside: Mapped[int] = mapped_column(Integer, default=0)
    outside_stored: Mapped[bool] = mapped_column(Boolean, default=False)
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    created_at: Mapped[dt.datetime] = _now()


class SoilSample(Base):
    __tablename__ = "soil_samples"
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    field_id: Mapped[int] = mapped_column(ForeignKey("fields.id", ondelete="CASCADE"), index=True)
    sample_id: Mapped[str] = mapped_column(String(100))
    depth_cm: Mapped[float | None] = mapped_column(Double)
    n_mg_kg: Mapped[float | None] = mapped_column(Double)
    p_mg_kg: Mapped[float | None] = mapped_column(Double)
    k_mg_kg: Mapped[float | None] = mapped_column(Double)
    om_pct: Mapped[float | None] = mapped_column(Double)
    ph: Mapped[float | None] = mapped_column(Double)
    ndvi: Mapped[float | None] = mapped_column(Double)
    # which N n_mg_kg is (agronomy.soil.N_FORMS): the nutrient-balance model reads only
    # alkali-hydrolysable N (seed 001 eq. 19-21)
    n_form: Mapped[str] = mapped_column(
        String(24), default="alkali_hydrolysable", server_default="alkali_hydrolysable"
    )
    geom: Mapped[Any] = mapped_column(Geometry("POINT", srid=4326, spatial_index=True))
    import_batch: Mapped[str] = mapped_column(String(64), default="")
    import_id: Mapped[int | None] = mapped_column(
        ForeignKey("soil_imports.id", ondelete="CASCADE"), index=True
    )
    created_at: Mapped[dt.datetime] = _now()


class Prescription(Base):
    __tablename__ = "prescriptions"
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    plan_id: Mapped[int] = mapped_column(ForeignKey("plans.id", ondelete="CASCADE"), index=True)
    # no foreign key into the distributed machines (migration 0017); unset on its delete
    machine_id: Mapped[int | None] = mapped_column(Integer)
    name: Mapped[str] = mapped_column(String(200), default="")
    product: Mapped[str] = mapped_column(String(200), default="")
    model: Mapped[str] = mapped_column(String(50))
    params: Mapped[dict[str, Any]] = mapped_column(JSONB, default=dict)
    current_version: Mapped[int] = mapped_column(Integer, default=1)
    created_at: Mapped[dt.datetime] = _now()


class Product(Base):
    """A fertiliser an organisation added to its catalogue (the defaults every
    organisation sees are in ``agronomy.products.DEFAULT_PRODUCTS``, not rows)."""

    __tablename__ = "products"
    __table_args__ = (
        UniqueConstraint("organisation_id", "name", name="uq_product_org_name"),
        CheckConstraint(
            "n_pct >= 0 AND p2o5_pct >= 0 AND k2o_pct >= 0 AND n_pct + p2o5_pct + k2o_pct <= 100",
            name="ck_product_pct",
        ),
        CheckConstraint("price_per_t IS NULL OR price_per_t >= 0", name="ck_product_price"),
        CheckConstraint(
            "density_kg_l IS NULL OR (density_kg_l >= 0.05 AND density_kg_l <= 5)",
            name="ck_product_density",
        ),
    )
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    name: Mapped[str] = mapped_column(String(200))
    n_pct: Mapped[float] = mapped_column(Double)
    p2o5_pct: Mapped[float] = mapped_column(Double, default=0.0)
    k2o_pct: Mapped[float] = mapped_column(Double, default=0.0)
    price_per_t: Mapped[float | None] = mapped_column(Double)
    # a liquid's density (kg/l), for ISOBUS volume-rate implements; NULL for solids
    density_kg_l: Mapped[float | None] = mapped_column(Double)
    created_at: Mapped[dt.datetime] = _now()


class PrescriptionVersion(Base):
    """An immutable version; an edit creates version n+1 and leaves n as it was."""

    __tablename__ = "prescription_versions"
    __table_args__ = (UniqueConstraint("prescription_id", "version"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    prescription_id: Mapped[int] = mapped_column(
        ForeignKey("prescriptions.id", ondelete="CASCADE"), index=True
    )
    version: Mapped[int] = mapped_column(Integer)
    note: Mapped[str] = mapped_column(Text, default="")
    summary: Mapped[dict[str, Any]] = mapped_column(JSONB, default=dict)
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    created_at: Mapped[dt.datetime] = _now()


class PrescriptionRate(Base):
    __tablename__ = "prescription_rates"
    version_id: Mapped[int] = mapped_column(
        ForeignKey("prescription_versions.id", ondelete="CASCADE"), primary_key=True
    )
    seq: Mapped[int] = mapped_column(Integer, primary_key=True)
    rate_kg_ha: Mapped[float] = mapped_column(Double)
    source_value: Mapped[float | None] = mapped_column(Double)  # interpolated N mg/kg or NDVI
    flags: Mapped[list[str]] = mapped_column(ARRAY(String(32)), default=list)


# Mapper arguments of the machine-keyed tables whose mapper key is ``id`` alone (the
# database's is (machine_id, id), migration 0017): the ORM's UPDATE and DELETE then say
# ``WHERE id = ? AND machine_id = ?``. Past one node (Citus) a statement naming the
# distribution column is a router plan on one shard; by ``id`` alone it runs on every shard.
# SQLAlchemy adds a "version" column to those WHERE clauses; with no generator the
# application sets the value (a row's machine never changes), so nothing else is written.
def machine_routed(machine_id: Any) -> dict[str, Any]:
    return {"version_id_col": machine_id, "version_id_generator": False}


class Job(Base):
    __tablename__ = "jobs"
    __table_args__ = (
        CheckConstraint(f"state IN {JOB_STATES}", name="ck_job_state"),
        CheckConstraint(f"kind IN {JOB_KINDS}", name="ck_job_kind"),
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
    created_at: Mapped[dt.datetime] = _now()
    updated_at: Mapped[dt.datetime] = _now()

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
    at: Mapped[dt.datetime] = _now()


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
    (``fieldrx_edge.protocol.CellRecord``), kept forever (migration 0011). Deduplicated by
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
    started_at: Mapped[dt.datetime] = _now()
    ended_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))
    acknowledged_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))
    acknowledged_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))

    __mapper_args__ = machine_routed(machine_id)


class JobArchive(Base):
    """A job's as-applied evidence kept after its machine, field, plan or prescription is
    deleted (migration 0007): no foreign key to any of them, only to the organisation."""

    __tablename__ = "job_archives"
    job_id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    name: Mapped[str] = mapped_column(String(200), default="", server_default="")
    archived_at: Mapped[dt.datetime] = _now()
    archived_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    summary: Mapped[dict[str, Any]] = mapped_column(JSONB)
    cells: Mapped[dict[str, Any]] = mapped_column(JSONB)


class LoginFailure(Base):
    """One failed sign-in, keyed by account (``email:...``) or address (``ip:...``)."""

    __tablename__ = "login_failures"
    __table_args__ = (Index("ix_login_failures_key_at", "key", "at"),)
    id: Mapped[int] = mapped_column(BigInteger, primary_key=True)
    key: Mapped[str] = mapped_column(String(400))
    at: Mapped[dt.datetime] = _now()


IMAGERY_KINDS = ("orthophoto", "ndvi", "multispectral")


class Imagery(Base):
    """An uploaded raster of a field, stored as a Cloud-Optimized GeoTIFF.

    ``storage_key`` is the COG's path relative to the imagery directory; ``bands`` maps
    roles to 1-based band numbers (``{"red": 3, "nir": 4}``, ``{"ndvi": 1}``,
    ``{"r": 1, "g": 2, "b": 3}``); ``footprint`` is the raster's outline in WGS84.
    """

    __tablename__ = "imagery"
    __table_args__ = (
        CheckConstraint("kind IN ('orthophoto', 'ndvi', 'multispectral')", name="ck_imagery_kind"),
        Index("ix_imagery_field_created", "field_id", "created_at"),
    )
    id: Mapped[int] = mapped_column(primary_key=True)
    organisation_id: Mapped[int] = mapped_column(
        ForeignKey("organisations.id", ondelete="CASCADE"), index=True
    )
    field_id: Mapped[int] = mapped_column(ForeignKey("fields.id", ondelete="CASCADE"))
    kind: Mapped[str] = mapped_column(String(20))
    name: Mapped[str] = mapped_column(String(200), default="")
    filename: Mapped[str] = mapped_column(String(255), default="")
    storage_key: Mapped[str] = mapped_column(String(255), unique=True)
    acquired_on: Mapped[dt.date | None] = mapped_column(Date)
    source_crs: Mapped[str] = mapped_column(Text, default="")
    resolution_m: Mapped[float] = mapped_column(Double)
    width: Mapped[int] = mapped_column(Integer)
    height: Mapped[int] = mapped_column(Integer)
    band_count: Mapped[int] = mapped_column(SmallInteger)
    dtype: Mapped[str] = mapped_column(String(20))
    bands: Mapped[dict[str, Any]] = mapped_column(JSONB, default=dict)
    nodata: Mapped[float | None] = mapped_column(Double)
    size_bytes: Mapped[int] = mapped_column(BigInteger)
    footprint: Mapped[Any] = mapped_column(Geometry("MULTIPOLYGON", srid=4326, spatial_index=True))
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    created_at: Mapped[dt.datetime] = _now()


class TaskKindRow(Base):
    """A kind of task (``tasks.kind`` refers to it): the rows are written from the
    task-kind registry (``tasks.kinds.sync_task_kinds``, run by ``fieldrx migrate``), so
    the database admits exactly the kinds the code registers without a migration per kind."""

    __tablename__ = "task_kinds"
    name: Mapped[str] = mapped_column(String(32), primary_key=True)


TASK_STATES = ("queued", "running", "succeeded", "failed", "cancelled")


class Task(Base):
    """Background work of an organisation: what the API and the UI see of a job on
    the PostgreSQL queue (procrastinate's ``procrastinate_jobs`` row ``job_id``).

    procrastinate knows how to run a job once and recover it from a dead worker; this row
    holds what FieldRx promises on top: organisation scoping, who asked, progress (0..1 and a
    message), the result (``{"plan_id": 7}``), the error a user can act on, and the
    cancellation request. A batch is a ``plan_batch`` row without a job whose children
    (``parent_id``) are the per-field tasks. The row is written in the same transaction as
    the work's result, which is what makes a retried job finish exactly once.
    """

    __tablename__ = "tasks"
    __table_args__ = (
        CheckConstraint(
            "status IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')",
            name="ck_tasks_status",
        ),
        CheckConstraint("progress >= 0 AND progress <= 1", name="ck_tasks_progress"),
        Index("ix_tasks_org_created", "organisation_id", "created_at"),
        Index("ix_tasks_parent", "parent_id"),
    )
    id: Mapped[int] = mapped_column(BigInteger, primary_key=True)
    organisation_id: Mapped[int] = mapped_column(ForeignKey("organisations.id", ondelete="CASCADE"))
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    parent_id: Mapped[int | None] = mapped_column(
        BigInteger, ForeignKey("tasks.id", ondelete="CASCADE")
    )
    kind: Mapped[str] = mapped_column(String(32), ForeignKey("task_kinds.name"))
    status: Mapped[str] = mapped_column(String(16), server_default="queued")
    progress: Mapped[float] = mapped_column(Double, server_default=text("0"))
    message: Mapped[str] = mapped_column(Text, server_default="")
    params: Mapped[dict[str, Any]] = mapped_column(JSONB, server_default=text("'{}'"))
    result: Mapped[dict[str, Any] | None] = mapped_column(JSONB)
    error: Mapped[str | None] = mapped_column(Text)
    cancel_requested: Mapped[bool] = mapped_column(Boolean, server_default=text("false"))
    job_id: Mapped[int | None] = mapped_column(BigInteger)
    attempts: Mapped[int] = mapped_column(Integer, server_default=text("0"))
    worker: Mapped[str] = mapped_column(String(200), server_default="")
    created_at: Mapped[dt.datetime] = _now()
    updated_at: Mapped[dt.datetime] = _now()
    started_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))
    finished_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True))


class TaskFile(Base):
    """The file a task produced (revision 0015): an export to download, or a job report's
    per-cell snapshot that API processes read instead of recomputing it. Written in the
    transaction that marks the task succeeded (one file per task however often it runs);
    deleted by workers after ``FIELDRX_TASK_RESULT_RETENTION_S`` (``tasks.files``)."""

    __tablename__ = "task_files"
    __table_args__ = (Index("ix_task_files_created", "created_at"),)
    task_id: Mapped[int] = mapped_column(
        BigInteger, ForeignKey("tasks.id", ondelete="CASCADE"), primary_key=True
    )
    organisation_id: Mapped[int] = mapped_column(ForeignKey("organisations.id", ondelete="CASCADE"))
    filename: Mapped[str] = mapped_column(String(300))
    media_type: Mapped[str] = mapped_column(String(100))
    size: Mapped[int] = mapped_column(BigInteger)
    data: Mapped[bytes] = mapped_column(LargeBinary)
    created_at: Mapped[dt.datetime] = _now()
