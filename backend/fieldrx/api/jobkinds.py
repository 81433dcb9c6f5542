"""Creating a sensor-kind job: seed 000 NDVI topdressing, seed 002 depth seeding.

The job names a plan (the path the tractor drives and the field boundary it keeps to) and
the kind's settings; ``fieldrx_edge.jobkinds.settings`` fills in the papers' defaults and
checks units and ranges, and the complete settings go into the job and its package. The
implement width is the machine's: a different ``implement_width_m`` is refused, an absent
one is taken from the machine and the job's first event says so.
"""

from __future__ import annotations

from typing import Any

from fieldrx_edge.jobkinds.settings import CONTROLLERS, DEFAULTS, KINDS, SettingsError
from fieldrx_edge.jobkinds.settings import validate_settings as validate

from fieldrx.api.common import ApiError
from fieldrx.db.models import Field, Job, JobEvent, Machine, Plan
from fieldrx.fleet.jobstate import notify_job
from fieldrx.services.implements import job_refusal
from fieldrx.services.prescriptions.meter import MeterSpec

__all__ = [
    "CONTROLLERS",
    "DEFAULTS",
    "KINDS",
    "check_machine_can",
    "create_kind_job",
    "kind_settings",
]


def check_machine_can(kind: str, machine: Machine) -> None:
    """422 naming what the machine lacks for a ``kind`` job (implement type, actuator,
    sensors); see ``services.implements``."""
    reason = job_refusal(kind, machine.implement_type, machine.capabilities)
    if reason is not None:
        raise ApiError(422, f"machine '{machine.name}': {reason}", where="machine_id")


KIND_LABELS = {
    "ndvi_topdress": "NDVI topdressing",
    "seeding_depth": "depth-controlled seeding",
}


def kind_settings(kind: str, given: dict[str, Any] | None, machine: Machine) -> tuple[dict, str]:
    """(complete settings, note for the job's history); ``ApiError`` 422 names the setting."""
    given = dict(given or {})
    note = ""
    if kind == "ndvi_topdress":
        w = given.get("implement_width_m")
        if w is None:
            given["implement_width_m"] = machine.width_m
            if abs(machine.width_m - DEFAULTS[kind]["implement_width_m"]) > 1e-9:
                note = (
                    f"implement width {machine.width_m:g} m from machine '{machine.name}'"
                    f" (seed 000's default is {DEFAULTS[kind]['implement_width_m']:g} m)"
                )
        elif isinstance(w, int | float) and abs(float(w) - machine.width_m) > 1e-6:
            raise ApiError(
                422,
                f"settings.implement_width_m {w:g} m differs from machine '{machine.name}'"
                f" ({machine.width_m:g} m): the rate is metered over the machine's width",
                where="settings.implement_width_m",
            )
    try:
        return validate(kind, given), note
    except SettingsError as exc:
        raise ApiError(422, str(exc), where=exc.where) from exc


def curve_meter_conflict(settings: dict[str, Any], machine: Machine) -> dict[str, Any] | None:
    """Where an NDVI job's rate curve (seed 000: 375 kg/ha at NDVI 0.24 down to 180 at
    0.65) leaves what the machine can meter over its speed range (seed 001 eq. 1-3, the
    check a prescription job's cells get): the curve's range, the meter's and a sentence;
    None when the whole curve is meterable or the machine has no calibration to check."""
    if not machine.calibration:
        return None
    curve = settings["rate_curve"]
    lo = min(curve["rate_at_lo_kg_ha"], curve["rate_at_hi_kg_ha"])
    hi = max(curve["rate_at_lo_kg_ha"], curve["rate_at_hi_kg_ha"])
    spec = MeterSpec(
        dict(machine.calibration), machine.width_m, machine.speed_min_m_s, machine.speed_max_m_s
    )
    try:
        meter = spec.describe()
    except ValueError as exc:
        return {"curve_kg_ha": [lo, hi], "meter": None, "message": str(exc)}
    m_lo, m_hi = meter["rate_min_kg_ha"], meter["rate_max_kg_ha"]
    if m_lo <= lo and hi <= m_hi:
        return None
    parts = []
    if lo < m_lo:
        parts.append(
            f"below {m_lo:.1f} kg/ha it applies {m_lo:.1f} kg/ha or more (over-application)"
        )
    if hi > m_hi:
        parts.append(f"above {m_hi:.1f} kg/ha it applies at most {m_hi:.1f} kg/ha")
    message = (
        f"the NDVI rate curve asks for {lo:.1f}..{hi:.1f} kg/ha but '{machine.name}' can meter "
        f"only {m_lo:.1f}..{m_hi:.1f} kg/ha at {meter['speed_min_kmh']:g}.."
        f"{meter['speed_max_kmh']:g} km/h: " + "; ".join(parts)
    )
    return {"curve_kg_ha": [lo, hi], "meter": meter, "message": message}


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
    conflict = curve_meter_conflict(settings, machine) if body.kind == "ndvi_topdress" else None
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
        name=body.name or f"{KIND_LABELS[body.kind]} on {field.name} with {machine.name}",
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
