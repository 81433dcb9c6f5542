"""Machines: implement geometry, metering calibration, lag time, controller; device tokens."""

from __future__ import annotations

import datetime as dt
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query
from fieldrx_edge.metering import calibration_from_dict
from fieldrx_edge.protocol import mqtt_username
from pydantic import BaseModel, Field, field_validator, model_validator
from sqlalchemy import func, select

from fieldrx.api.common import ApiError, get_scoped
from fieldrx.auth.deps import AnyPrincipal, SessionDep, UserDep, WriterDep
from fieldrx.auth.mqtt import revoke_device_after
from fieldrx.auth.service import issue_device_token, token_expiry
from fieldrx.db.models import Machine
from fieldrx.services.evidence import refuse_if_evidence

router = APIRouter(prefix="/machines", tags=["machines"])

CONTROLLERS = ("pid", "incremental_pid", "ladrc", "fuzzy_pid")


class ControllerIn(BaseModel):
    name: Literal["pid", "incremental_pid", "ladrc", "fuzzy_pid"] = "ladrc"
    params: dict[str, float] = Field(default_factory=dict)
    period_s: float = Field(default=0.01, gt=0, le=1)


class LinearCalibrationIn(BaseModel):
    """Seed 001 eq. 1 form of a meter's calibration: q0 = a * r + b [g/min], r in r/min.

    Every field is required: a machine's calibration is measured on that machine,
    so there is no default (seed 001's disc spreader is a = 237.2, b = -404.4,
    30..130 r/min).
    """

    kind: Literal["linear"] = "linear"
    slope_g_min_per_rpm: float = Field(gt=0, description="a: g/min per r/min")
    intercept_g_min: float = Field(description="b: g/min at r = 0 (may be negative)")
    min_rpm: float = Field(ge=0, description="lowest stable shaft speed, r/min")
    max_rpm: float = Field(gt=0, le=10000, description="highest shaft speed, r/min")

    @model_validator(mode="after")
    def _range(self) -> LinearCalibrationIn:
        if self.max_rpm <= self.min_rpm:
            raise ValueError(
                f"max_rpm ({self.max_rpm:g}) must be greater than min_rpm ({self.min_rpm:g})"
            )
        q_min = self.slope_g_min_per_rpm * self.min_rpm + self.intercept_g_min
        if q_min <= 0:
            raise ValueError(
                f"the meter delivers {q_min:g} g/min at min_rpm {self.min_rpm:g} r/min "
                "(a * min_rpm + b must be > 0): raise min_rpm to where it meters"
            )
        return self


class TableCalibrationIn(BaseModel):
    """Seed 000 form: discharge per revolution measured at several shaft speeds."""

    kind: Literal["table"]
    rpm: list[float] = Field(min_length=2)
    g_per_rev: list[float] = Field(min_length=2)
    min_rpm: float = Field(ge=0)
    max_rpm: float = Field(gt=0, le=10000)

    @model_validator(mode="after")
    def _table(self) -> TableCalibrationIn:
        if self.max_rpm <= self.min_rpm:
            raise ValueError(
                f"max_rpm ({self.max_rpm:g}) must be greater than min_rpm ({self.min_rpm:g})"
            )
        calibration_from_dict(self.model_dump())  # monotone flow, equal lengths
        return self


CalibrationIn = Annotated[LinearCalibrationIn | TableCalibrationIn, Field(discriminator="kind")]


def _calibration_dict(value: Any) -> Any:
    """Calibrations without ``kind`` are the linear (seed 001 eq. 1) form."""
    if isinstance(value, dict) and "kind" not in value:
        return {**value, "kind": "linear"}
    return value


class MachineIn(BaseModel):
    name: str = Field(min_length=1, max_length=200)
    implement_type: str = Field(default="spreader", max_length=50)
    # >= 5 cm: a narrower "implement" only makes rate = flow / (w v) overflow (ISSUE 20)
    width_m: float = Field(ge=0.05, le=60, description="working width, m")
    lag_s: float = Field(ge=0, le=30, description="application lag T_lag, s (seed 001: 1.52)")
    calibration: CalibrationIn = Field(
        description="metering calibration, measured on this machine (no default)"
    )
    controller: ControllerIn = Field(default_factory=ControllerIn)
    antenna_forward_m: float = 0.0
    antenna_lateral_m: float = 0.0
    speed_min_m_s: float = Field(default=0.8, ge=0.01, le=30)
    speed_max_m_s: float = Field(default=2.5, ge=0.01, le=30)

    @field_validator("calibration", mode="before")
    @classmethod
    def _kind(cls, value: Any) -> Any:
        return _calibration_dict(value)


class MachinePatch(BaseModel):
    name: str | None = Field(default=None, min_length=1, max_length=200)
    implement_type: str | None = Field(default=None, max_length=50)
    width_m: float | None = Field(default=None, ge=0.05, le=60)
    lag_s: float | None = Field(default=None, ge=0, le=30)
    calibration: CalibrationIn | None = None
    controller: ControllerIn | None = None
    antenna_forward_m: float | None = None
    antenna_lateral_m: float | None = None
    speed_min_m_s: float | None = Field(default=None, ge=0.01, le=30)
    speed_max_m_s: float | None = Field(default=None, ge=0.01, le=30)

    @field_validator("calibration", mode="before")
    @classmethod
    def _kind(cls, value: Any) -> Any:
        return _calibration_dict(value)


class MachineOut(BaseModel):
    id: int
    name: str
    implement_type: str
    width_m: float
    lag_s: float
    calibration: dict[str, Any]
    controller: dict[str, Any]
    antenna_forward_m: float
    antenna_lateral_m: float
    speed_min_m_s: float
    speed_max_m_s: float
    created_at: dt.datetime


class MachineList(BaseModel):
    items: list[MachineOut]
    total: int


class DeviceTokenOut(BaseModel):
    machine_id: int
    token: str
    mqtt_username: str = Field(
        description="MQTT user name of the machine; its MQTT password is this token"
    )
    expires_at: dt.datetime | None = None


def _out(m: Machine) -> MachineOut:
    return MachineOut.model_validate(m, from_attributes=True)


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
) -> MachineList:
    stmt = select(Machine).where(Machine.organisation_id == principal.organisation_id)
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
