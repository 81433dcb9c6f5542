"""Creating a sensor-kind job (its rates decided on the go: seed 000 NDVI topdressing,
seed 002 depth seeding).

The job names a plan (the path the tractor drives and the field boundary it keeps to) and
the kind's settings; ``fieldrx_edge.jobkinds.settings`` fills in the papers' defaults and
checks units and ranges, and the complete settings go into the job and its package. A
kind's server hooks (``fieldrx.jobkinds``) add its own checks: e.g. the NDVI kind takes the
implement width from the machine and checks its rate curve against the meter.
"""

from __future__ import annotations

from typing import Any

from fieldrx_edge.jobkinds.registry import kind_of
from fieldrx_edge.jobkinds.settings import SettingsError
from fieldrx_edge.jobkinds.settings import validate_settings as validate

from fieldrx.api.common import ApiError
from fieldrx.db.models import Field, Job, JobEvent, Machine, Plan
from fieldrx.fleet.jobstate import notify_job
from fieldrx.jobkinds.registry import hooks
from fieldrx.services.implements import job_refusal

__all__ = ["check_machine_can", "create_kind_job", "kind_settings"]


def check_machine_can(kind: str, machine: Machine) -> None:
    """422 naming what the machine lacks for a ``kind`` job (implement type, actuator,
    sensors); see ``services.implements``."""
    reason = job_refusal(kind, machine.implement_type, machine.capabilities)
    if reason is not None:
        raise ApiError(422, f"machine '{machine.name}': {reason}", where="machine_id")


def kind_settings(kind: str, given: dict[str, Any] | None, machine: Machine) -> tuple[dict, str]:
    """(complete settings, note for the job's history); ``ApiError`` 422 names the setting.
    The kind's ``prepare`` hook (``fieldrx.jobkinds``) may take values from the machine."""
    given = dict(given or {})
    note = ""
    prepare = hooks(kind).prepare
    try:
        if prepare is not None:
            given, note = prepare(given, machine)
        return validate(kind, given), note
    except SettingsError as exc:
        raise ApiError(422, str(exc), where=exc.where) from exc


def create_kind_job(session: Any, principal: Any, body: Any) -> Job:
    """Validate and store a sensor-kind job (state planned) and its first event."""
    if body.prescription_id is not None or body.prescription_version is not None:
        raise ApiError(
            422,
            f"a {body.kind} job decides its rates from sensors: leave prescription_id out"
            " and give plan_id",
            where="prescription_id",
        )
    if body.plan_id is None:
        raise ApiError(422, f"a {body.kind} job needs plan_id (the path to drive)", where="plan_id")
    plan = session.get(Plan, body.plan_id)
    field = session.get(Field, plan.field_id) if plan is not None else None
    if field is None or field.organisation_id != principal.organisation_id:
        raise ApiError(404, f"plan {body.plan_id} not found", where="plan_id")
    machine = session.get(Machine, body.machine_id)
    if machine is None or machine.organisation_id != principal.organisation_id:
        raise ApiError(404, f"machine {body.machine_id} not found", where="machine_id")
    check_machine_can(body.kind, machine)
    swath = float((plan.params or {}).get("swath_width_m") or 0.0)
    if swath > 0 and abs(machine.width_m - swath) > 0.01 * swath:
        raise ApiError(
            422,
            f"machine '{machine.name}' works {machine.width_m:g} m wide but plan {plan.id}"
            f" was planned with {swath:g} m swaths; plan the field again with the machine's width",
            where="machine_id",
        )
    settings, note = kind_settings(body.kind, body.settings, machine)
    meter_conflict = hooks(body.kind).meter_conflict
    conflict = meter_conflict(settings, machine) if meter_conflict is not None else None
    if conflict is not None and not body.confirm_flagged:
        raise ApiError(
            409,
            f"{conflict['message']}; confirm to send it anyway",
            where="confirm_flagged",
            meter_conflict=conflict,
        )
    if conflict is not None:
        note = "; ".join(
            x for x in (note, f"sent with a confirmed meter conflict: {conflict['message']}") if x
        )
    job = Job(
        organisation_id=principal.organisation_id,
        kind=body.kind,
        settings=settings,
        plan_id=plan.id,
        machine_id=machine.id,
        name=body.name or f"{kind_of(body.kind).noun} on {field.name} with {machine.name}",
        state="planned",
        n_cells=int(plan.n_cells or 0),
        cells_applied=0,
        package_checksum="",
        flagged_confirmed=conflict is not None,
        created_by=principal.user_id,
    )
    session.add(job)
    session.flush()
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
    return job
