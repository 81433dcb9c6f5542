"""Jobs: a prescription version bound to a machine, and its life from planned to completed."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Query
from fieldrx_edge.jobkinds.registry import kind_of, kinds
from sqlalchemy import func, select

from fieldrx.api.common import ApiError, get_scoped
from fieldrx.api.jobkinds import check_machine_can, create_kind_job
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.jobs import (
    EventOut,
    JobIn,
    JobList,
    JobOut,
    KindsOut,
    State,
    StateIn,
)
from fieldrx.auth.deps import SessionDep, UserDep, WriterDep
from fieldrx.db.models import (
    JOB_STATES,
    Job,
    JobEvent,
    Machine,
    Plan,
    Prescription,
    PrescriptionRate,
    PrescriptionVersion,
)
from fieldrx.db.models import Field as FieldRow
from fieldrx.fleet.jobstate import change_state, lock_job, notify_job
from fieldrx.services.imports import IMPORTED_IMPLEMENT
from fieldrx.services.prescriptions import meter as rx_svc
from fieldrx.services.prescriptions.params import rx_rate_unit

router = APIRouter(prefix="/jobs", tags=["jobs"], responses=ERRORS)


def job_context(session: SessionDep, jobs: list[Job]) -> dict[int, dict[str, Any]]:
    """What a jobs list shows beside each job (machine and field names, product, when it
    started and ended), in five queries for the whole page."""
    if not jobs:
        return {}
    ids = [j.id for j in jobs]
    rxs = {
        r.id: (r.product, r.plan_id)
        for r in session.execute(
            select(Prescription.id, Prescription.product, Prescription.plan_id).where(
                Prescription.id.in_({j.prescription_id for j in jobs if j.prescription_id})
            )
        )
    }
    plan_of = {j.id: j.plan_id or rxs.get(j.prescription_id or 0, (None, None))[1] for j in jobs}
    fields_ = {
        pid: (fid, name)
        for pid, fid, name in session.execute(
            select(Plan.id, FieldRow.id, FieldRow.name)
            .join(FieldRow, FieldRow.id == Plan.field_id)
            .where(Plan.id.in_({p for p in plan_of.values() if p}))
        )
    }
    machines = dict(
        session.execute(
            select(Machine.id, Machine.name).where(Machine.id.in_({j.machine_id for j in jobs}))
        ).all()
    )
    started = dict(
        session.execute(
            select(JobEvent.job_id, func.min(JobEvent.at))
            .where(JobEvent.job_id.in_(ids), JobEvent.state == "running")
            .group_by(JobEvent.job_id)
        ).all()
    )
    ended = dict(
        session.execute(
            select(JobEvent.job_id, func.max(JobEvent.at))
            .where(JobEvent.job_id.in_(ids), JobEvent.state.in_(("completed", "aborted")))
            .group_by(JobEvent.job_id)
        ).all()
    )
    out: dict[int, dict[str, Any]] = {}
    for j in jobs:
        fid, fname = fields_.get(plan_of[j.id] or 0, (None, None))
        out[j.id] = {
            "machine_name": machines.get(j.machine_id),
            "field_id": fid,
            "field_name": fname,
            "product": rxs[j.prescription_id][0] if j.prescription_id in rxs else None,
            "started_at": started.get(j.id),
            "ended_at": ended.get(j.id),
        }
    return out


def job_out(
    job: Job, events: list[JobEvent] | None = None, context: dict[str, Any] | None = None
) -> JobOut:
    return JobOut(
        **(context or {}),
        id=job.id,
        name=job.name,
        state=job.state,
        kind=job.kind,
        prescription_id=job.prescription_id,
        prescription_version=job.prescription_version,
        plan_id=job.plan_id,
        settings=dict(job.settings or {}),
        machine_id=job.machine_id,
        n_cells=job.n_cells,
        cells_applied=job.cells_applied,
        progress=(job.cells_applied / job.n_cells) if job.n_cells else 0.0,
        package_checksum=job.package_checksum,
        flagged_cells=job.flagged_cells or 0,
        flagged_confirmed=bool(job.flagged_confirmed),
        created_by=job.created_by,
        created_at=job.created_at,
        updated_at=job.updated_at,
        events=None
        if events is None
        else [EventOut.model_validate(e, from_attributes=True) for e in events],
    )


def _events(session: SessionDep, job: Job) -> list[JobEvent]:
    where = (JobEvent.machine_id == job.machine_id, JobEvent.job_id == job.id)
    return list(session.scalars(select(JobEvent).where(*where).order_by(JobEvent.id)))


def _check_width(session: SessionDep, rx: Prescription, machine: Machine) -> None:
    """The grid's cells are one swath wide: a machine of another width would meter wrongly."""
    plan = session.get(Plan, rx.plan_id)
    swath = float((plan.params or {}).get("swath_width_m") or 0.0) if plan else 0.0
    if swath > 0 and abs(machine.width_m - swath) > 0.01 * swath:
        raise ApiError(
            422,
            f"machine '{machine.name}' works {machine.width_m:g} m wide but plan {rx.plan_id}"
            f" was planned with {swath:g} m swaths; plan the field again with the machine's width",
            where="machine_id",
        )


def _attention(
    session: SessionDep, rx: Prescription, v: PrescriptionVersion, machine: Machine
) -> dict:
    try:
        return rx_svc.job_attention(session, rx, v, machine)
    except (LookupError, ValueError) as exc:
        raise ApiError(422, str(exc), where="prescription_id") from exc


@router.post("", response_model=JobOut, status_code=201)
def create_job(body: JobIn, principal: WriterDep, session: SessionDep) -> JobOut:
    if kind_of(body.kind).rates_from == "sensors":
        job = create_kind_job(session, principal, body)
        return job_out(job, _events(session, job))
    if body.prescription_id is None:
        raise ApiError(422, f"a {body.kind} job needs prescription_id", where="prescription_id")
    if body.plan_id is not None or body.settings:
        raise ApiError(
            422,
            f"a {body.kind} job takes its path and rates from the prescription: "
            "leave plan_id and settings out",
            where="settings" if body.settings else "plan_id",
        )
    rx = session.get(Prescription, body.prescription_id)
    if rx is None or rx.organisation_id != principal.organisation_id:
        raise ApiError(
            404, f"prescription {body.prescription_id} not found", where="prescription_id"
        )
    unit = rx_rate_unit(rx)[0]
    taken = kind_of(body.kind).rate_units
    if unit not in taken:
        raise ApiError(
            422,
            f"prescription {rx.id} is in {unit}: a {body.kind} job takes prescriptions in "
            f"{' or '.join(taken)}",
            where="prescription_id",
        )
    machine = session.get(Machine, body.machine_id)
    if machine is None or machine.organisation_id != principal.organisation_id:
        raise ApiError(404, f"machine {body.machine_id} not found", where="machine_id")
    if machine.implement_type == IMPORTED_IMPLEMENT:
        raise ApiError(
            422,
            f"machine {machine.id} ({machine.name}) holds imported logs, it is no real "
            "machine: a job cannot be sent to it",
            where="machine_id",
        )
    version = (
        body.prescription_version if body.prescription_version is not None else rx.current_version
    )
    v = session.scalar(
        select(PrescriptionVersion).where(
            PrescriptionVersion.prescription_id == rx.id, PrescriptionVersion.version == version
        )
    )
    if v is None:
        raise ApiError(
            404, f"prescription {rx.id} has no version {version}", where="prescription_version"
        )
    check_machine_can(body.kind, machine)
    _check_width(session, rx, machine)
    attention = _attention(session, rx, v, machine)
    if attention["count"] and not body.confirm_flagged:
        m = attention["meter"]
        raise ApiError(
            409,
            f"prescription {rx.id} v{version} has {attention['count']} cell(s) "
            f"({attention['area_m2'] / 1e4:.4f} ha) that '{machine.name}' will not apply as "
            f"prescribed or that need a second look: {attention['no_data']} with no soil data "
            f"(fallback rate), {attention['out_of_meter_range']} outside the meter range "
            f"{m['rate_min_kg_ha']:.1f}..{m['rate_max_kg_ha']:.1f} kg/ha at "
            f"{m['speed_min_kmh']:g}..{m['speed_max_kmh']:g} km/h, "
            f"{attention['above_nutrient_ceiling']} above a nutrient ceiling, "
            f"{attention['at_curve_limit']} at a rate curve's cap or floor; confirm these cells to "
            "send it anyway",
            where="confirm_flagged",
            flagged=attention,
        )
    n_cells = session.scalar(
        select(func.count())
        .select_from(PrescriptionRate)
        .where(PrescriptionRate.version_id == v.id)
    )
    job = Job(
        organisation_id=principal.organisation_id,
        kind=body.kind,
        prescription_id=rx.id,
        prescription_version=version,
        machine_id=machine.id,
        name=body.name or f"{rx.name or 'prescription ' + str(rx.id)} v{version} on {machine.name}",
        state="planned",
        n_cells=n_cells or 0,
        cells_applied=0,
        package_checksum="",
        flagged_cells=attention["count"],
        flagged_confirmed=bool(attention["count"]) and body.confirm_flagged,
        created_by=principal.user_id,
    )
    session.add(job)
    session.flush()
    note = (
        f"sent with {attention['count']} flagged cell(s) confirmed: {attention['no_data']} no "
        f"data, {attention['out_of_meter_range']} outside the meter range, "
        f"{attention['above_nutrient_ceiling']} above a nutrient ceiling, "
        f"{attention['at_curve_limit']} at a rate curve's cap or floor"
        if job.flagged_confirmed
        else ""
    )
    session.add(
        JobEvent(
            job_id=job.id,
            machine_id=job.machine_id,
            state="planned",
            by_user_id=principal.user_id,
            note=note,
        )
    )
    session.flush()
    session.refresh(job)
    notify_job(session, job)
    session.commit()
    return job_out(job, _events(session, job))


@router.get("/kinds", response_model=KindsOut)
def job_kinds(principal: UserDep) -> dict[str, Any]:
    """Every job kind of the registry (``fieldrx_edge.jobkinds``), in list order: its label,
    paper, where its rates come from, what the machine needs, its default settings (the
    papers' values, units in the names), controllers, and the form's inputs with unit,
    default and the default's source."""
    return {"kinds": {k.name: k.describe() for k in kinds()}}


@router.get("", response_model=JobList)
def list_jobs(
    principal: UserDep,
    session: SessionDep,
    state: list[State] | None = Query(default=None, description="filter; repeat for several"),
    machine_id: int | None = None,
    prescription_id: int | None = None,
    limit: int = Query(default=100, ge=1, le=1000),
    offset: int = Query(default=0, ge=0),
) -> JobList:
    stmt = select(Job).where(Job.organisation_id == principal.organisation_id)
    if state:
        stmt = stmt.where(Job.state.in_(state))
    if machine_id is not None:
        stmt = stmt.where(Job.machine_id == machine_id)
    if prescription_id is not None:
        stmt = stmt.where(Job.prescription_id == prescription_id)
    total = session.scalar(select(func.count()).select_from(stmt.subquery())) or 0
    rows = list(session.scalars(stmt.order_by(Job.id.desc()).limit(limit).offset(offset)))
    ctx = job_context(session, rows)
    return JobList(items=[job_out(j, context=ctx[j.id]) for j in rows], total=total)


@router.get("/{job_id:int}", response_model=JobOut)
def get_job(job_id: int, principal: UserDep, session: SessionDep) -> JobOut:
    """The job with its events, machine and field names, product, start and end."""
    job = get_scoped(session, Job, job_id, principal)
    return job_out(job, _events(session, job), job_context(session, [job])[job.id])


@router.post("/{job_id:int}/state", response_model=JobOut)
def set_state(job_id: int, body: StateIn, principal: WriterDep, session: SessionDep) -> JobOut:
    job = get_scoped(session, Job, job_id, principal)
    lock_job(session, job)
    if body.state == "sent" and job.state != "sent":
        # the machine may have changed since the job was made (implement, sensors)
        machine = session.get(Machine, job.machine_id)
        if machine is not None:
            check_machine_can(job.kind, machine)
    change_state(session, job, body.state, user_id=principal.user_id, note=body.note)
    session.commit()
    return job_out(job, _events(session, job))


assert set(JOB_STATES) == set(State.__args__)  # type: ignore[attr-defined]
