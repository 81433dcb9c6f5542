"""Job package from the database: a prescription version bound to a machine
(docs/architecture.md, data flow step 5).

For the fleet helper's ``/api/v1/device/jobs/{id}/package``: call

    build_job_package(session, job) -> fieldrx_edge.job_package.JobPackage   (sealed)

or, without a job row, ``build_package(session, prescription_id, version, machine, job_id=0)``.
Cells come from ``plan_cells`` in path order (UTM corners straight from
``plan_cells.corners_utm``, WGS84 corners through fieldrx.geo.crs), rates from
``prescription_rates`` of that version, the boundary in the field's UTM zone.
The real cell shapes of edge, hole and headland cells (``JobPackage.shape_*``)
come from the cell store (``fieldrx.store.load_cells``: a split cell whole, as a
MultiPolygon), back in UTM; ``build_job_package`` keeps those that
differ from their rectangle.
The serialising (rounding, checksum) is fieldrx.formats.jobpackage's.
Raises ``LookupError`` when the prescription, version, plan or field is missing.
"""

from __future__ import annotations

from typing import Any

from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.jobkinds.registry import DEFAULT_KIND, kind_of
from sqlalchemy.orm import Session

from fieldrx.db.models import Field, Job, Machine, Plan, Prescription
from fieldrx.services.plans import field_utm
from fieldrx.services.prescriptions.params import rx_unit_lot
from fieldrx.services.prescriptions.versions import get_version, version_cells
from fieldrx.store import load_cells


def machine_fields(machine: Machine) -> dict[str, Any]:
    """The machine's part of a job package (width, lag, calibration, controller, antenna
    offset, speed range): one list for every job kind."""
    return {
        "implement_width_m": machine.width_m,
        "lag_s": machine.lag_s,
        "calibration": dict(machine.calibration),
        "controller": dict(machine.controller or {}) or None,
        "antenna_forward_m": machine.antenna_forward_m,
        "antenna_lateral_m": machine.antenna_lateral_m,
        "speed_min_m_s": machine.speed_min_m_s,
        "speed_max_m_s": machine.speed_max_m_s,
    }


def build_package(
    session: Session,
    prescription_id: int,
    version: int | None,
    machine: Machine,
    job_id: int = 0,
    kind: str = DEFAULT_KIND,
) -> JobPackage:
    """Sealed JobPackage of one prescription version for one machine (version None = current)."""
    from fieldrx.formats.jobpackage import JobPackageSpec
    from fieldrx.formats.jobpackage import build_job_package as build

    rx = session.get(Prescription, prescription_id)
    if rx is None:
        raise LookupError(f"prescription {prescription_id} not found")
    ver = get_version(session, rx, version)
    plan = session.get(Plan, rx.plan_id)
    field = session.get(Field, plan.field_id) if plan is not None else None
    if plan is None or field is None:
        raise LookupError(f"prescription {prescription_id}: plan or field is gone")
    cells = version_cells(session, rx, ver)
    unit, lot = rx_unit_lot(rx)
    if unit.lot:
        # stored in kg/ha (the agronomy counts mass); the package carries the prescription's
        # unit (a liquid by volume), so an ISOBUS implement metering in it (DDI 1 for l/ha)
        # takes the rates as they are; check_rate_unit made sure the lot converts
        cells = cells.with_rates(cells.rate_kg_ha / unit.kg_per_unit(unit.check_lot(lot)))
    density = lot.pop("density_kg_l", None)
    return build(
        cells,
        field_utm(field),
        JobPackageSpec(
            job_id=job_id,
            machine_id=machine.id,
            prescription_id=rx.id,
            prescription_version=ver.version,
            field_name=field.name,
            **machine_fields(machine),
            product=rx.product,
            kind=kind,
            # the product's lot travels with it (ISOBUS volume-rate implements, DDI 1)
            rate_unit=unit.name,
            product_density_kg_l=density or 0.0,
            unit_lot=lot,
        ),
    )


def build_kind_package(session: Session, job: Job, machine: Machine) -> JobPackage:
    """Sealed JobPackage of a sensor-kind job: the plan's cells in path order
    (the path the tractor drives; rates 0, the sensors decide them), the field boundary,
    and the kind with its validated settings."""
    from fieldrx.formats.jobpackage import JobPackageSpec
    from fieldrx.formats.jobpackage import build_job_package as build

    plan = session.get(Plan, job.plan_id)
    field = session.get(Field, plan.field_id) if plan is not None else None
    if plan is None or field is None:
        raise LookupError(f"job {job.id}: plan {job.plan_id} or its field is gone")
    cells = load_cells(session, plan.id, field.utm_epsg)
    return build(
        cells,
        field_utm(field),
        JobPackageSpec(
            job_id=job.id,
            machine_id=machine.id,
            prescription_id=0,
            prescription_version=0,
            field_name=field.name,
            **machine_fields(machine),
            kind=job.kind,
            kind_settings=dict(job.settings or {}),
        ),
    )


def build_job_package(session: Session, job: Job) -> JobPackage:
    """Sealed JobPackage of a job row (its prescription version, or its plan and kind, and
    machine)."""
    machine = session.get(Machine, job.machine_id)
    if machine is None:
        raise LookupError(f"job {job.id}: machine {job.machine_id} not found")
    if kind_of(job.kind).rates_from == "sensors":
        return build_kind_package(session, job, machine)
    if job.prescription_id is None:
        raise LookupError(f"job {job.id}: a prescription-map job without a prescription")
    return build_package(
        session, job.prescription_id, job.prescription_version, machine, job.id, job.kind
    )
