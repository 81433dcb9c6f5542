"""Machines: implement geometry, metering calibration, lag time, controller; device tokens."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Query
from fieldrx_edge.metering import calibration_from_dict
from fieldrx_edge.protocol import mqtt_username
from sqlalchemy import delete, func, select, update

from fieldrx.api.common import ApiError, get_scoped
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.machines import (
    DeviceTokenOut,
    LinearCalibrationIn,
    MachineIn,
    MachineList,
    MachineOut,
    MachinePatch,
    TableCalibrationIn,
)
from fieldrx.auth.deps import AnyPrincipal, SessionDep, UserDep, WriterDep
from fieldrx.auth.mqtt import revoke_device_after
from fieldrx.auth.service import issue_device_token, token_expiry
from fieldrx.db.models import ApiToken, Machine, Prescription
from fieldrx.services.evidence import refuse_if_evidence
from fieldrx.services.implements import capabilities
from fieldrx.services.imports import IMPORTED_IMPLEMENT

router = APIRouter(prefix="/machines", tags=["machines"], responses=ERRORS)



def _out(m: Machine) -> MachineOut:
    out = MachineOut.model_validate(m, from_attributes=True)
    out.capabilities = capabilities(m.capabilities)
    return out


def _stored_calibration(cal: LinearCalibrationIn | TableCalibrationIn) -> dict[str, Any]:
    """The JSON form the job package and the edge agent read (fieldrx_edge.metering)."""
    return calibration_from_dict(cal.model_dump()).to_dict()


def _check_speeds(m: Machine) -> None:
    if m.speed_min_m_s > m.speed_max_m_s:
        raise ApiError(422, "speed_min_m_s is greater than speed_max_m_s", where="speed_min_m_s")


@router.get("", response_model=MachineList)
def list_machines(
    principal: UserDep,
    session: SessionDep,
    limit: int = Query(default=100, ge=1, le=1000),
    offset: int = Query(default=0, ge=0),
    sendable: bool = Query(
        default=False,
        description="only machines a job can be sent to (not those an import created for logs)",
    ),
) -> MachineList:
    stmt = select(Machine).where(Machine.organisation_id == principal.organisation_id)
    if sendable:
        stmt = stmt.where(Machine.implement_type != IMPORTED_IMPLEMENT)
    total = session.scalar(select(func.count()).select_from(stmt.subquery())) or 0
    rows = session.scalars(stmt.order_by(Machine.id).limit(limit).offset(offset))
    return MachineList(items=[_out(r) for r in rows], total=total)


@router.post("", response_model=MachineOut, status_code=201)
def create_machine(body: MachineIn, principal: WriterDep, session: SessionDep) -> MachineOut:
    m = Machine(organisation_id=principal.organisation_id, **body.model_dump())
    m.calibration = _stored_calibration(body.calibration)
    _check_speeds(m)
    session.add(m)
    session.commit()
    return _out(m)


@router.get("/{machine_id:int}", response_model=MachineOut)
def get_machine(machine_id: int, principal: AnyPrincipal, session: SessionDep) -> MachineOut:
    """Users see their organisation's machines; a device token sees only its own machine."""
    if principal.is_device and principal.machine_id != machine_id:
        raise ApiError(404, f"machine {machine_id} not found")
    return _out(get_scoped(session, Machine, machine_id, principal))


@router.patch("/{machine_id:int}", response_model=MachineOut)
def update_machine(
    machine_id: int, body: MachinePatch, principal: WriterDep, session: SessionDep
) -> MachineOut:
    m = get_scoped(session, Machine, machine_id, principal)
    for key, value in body.model_dump(exclude_unset=True).items():
        if value is not None:
            setattr(m, key, value)
    if body.calibration is not None:
        m.calibration = _stored_calibration(body.calibration)
    _check_speeds(m)
    session.commit()
    return _out(m)


@router.delete("/{machine_id:int}", status_code=204)
def delete_machine(machine_id: int, principal: WriterDep, session: SessionDep) -> None:
    """Delete the machine and its jobs; 409 while a job holds unarchived as-applied data."""
    machine = get_scoped(session, Machine, machine_id, principal)
    refuse_if_evidence(session, "machine", machine.id)
    # no foreign keys from these coordinator tables into the distributed machines
    # (migration 0017): the cascade and the SET NULL they had, done here
    session.execute(delete(ApiToken).where(ApiToken.machine_id == machine.id))
    session.execute(
        update(Prescription).where(Prescription.machine_id == machine.id).values(machine_id=None)
    )
    session.delete(machine)
    session.commit()
    revoke_device_after(machine_id, f"machine {machine_id} is deleted")  # and its MQTT user


@router.post("/{machine_id:int}/device-token", response_model=DeviceTokenOut, status_code=201)
def new_device_token(machine_id: int, principal: WriterDep, session: SessionDep) -> DeviceTokenOut:
    """Issue the machine's device token (shown once); earlier tokens of the machine are revoked."""
    m = get_scoped(session, Machine, machine_id, principal)
    token = issue_device_token(session, m.id, m.organisation_id)
    session.commit()
    return DeviceTokenOut(
        machine_id=m.id,
        token=token,
        mqtt_username=mqtt_username(m.id),
        expires_at=token_expiry(session, token),
    )
