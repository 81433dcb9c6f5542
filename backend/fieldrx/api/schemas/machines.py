"""Machines: implement geometry, metering calibration, lag time, controller; device tokens."""

from __future__ import annotations

import datetime as dt
from typing import Annotated, Any, Literal

from fieldrx_edge.metering import calibration_from_dict
from pydantic import Field, field_validator, model_validator

from fieldrx.api.schemas.base import In, Out


class ControllerIn(In):
    name: Literal["pid", "incremental_pid", "ladrc", "fuzzy_pid"] = "ladrc"
    params: dict[str, float] = Field(default_factory=dict)
    period_s: float = Field(default=0.01, gt=0, le=1)


class LinearCalibrationIn(In):
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


class TableCalibrationIn(In):
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


def calibration_kind(value: Any) -> Any:
    """Calibrations without ``kind`` are the linear (seed 001 eq. 1) form."""
    if isinstance(value, dict) and "kind" not in value:
        return {**value, "kind": "linear"}
    return value


ImplementType = Literal["spreader", "seeder", "seed_fertiliser_drill", "sprayer", "imported"]
Sensor = Literal["canopy_ndvi", "depth"]


class CapabilitiesIn(In):
    """What the implement can do beyond metering (checked when a job is made and sent)."""

    sections: int = Field(default=1, ge=1, le=256, description="switchable sections")
    depth_actuator: bool = Field(
        default=False, description="sowing-depth actuator (seed 002's hydraulic cylinder)"
    )
    sensors: list[Sensor] = Field(
        default_factory=list,
        description="canopy_ndvi: crop canopy NDVI sensors (seed 000); depth: sowing-depth "
        "sensor (seed 002)",
    )


class MachineIn(In):
    name: str = Field(min_length=1, max_length=200)
    implement_type: ImplementType = Field(default="spreader")
    capabilities: CapabilitiesIn = Field(default_factory=CapabilitiesIn)
    # >= 5 cm: a narrower "implement" only makes rate = flow / (w v) overflow
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
        return calibration_kind(value)


class MachinePatch(In):
    name: str | None = Field(default=None, min_length=1, max_length=200)
    implement_type: ImplementType | None = None
    capabilities: CapabilitiesIn | None = None
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
        return calibration_kind(value)


class MachineOut(Out):
    id: int
    name: str
    implement_type: str
    capabilities: dict[str, Any]
    width_m: float
    lag_s: float
    calibration: dict[str, Any]
    controller: dict[str, Any]
    antenna_forward_m: float
    antenna_lateral_m: float
    speed_min_m_s: float
    speed_max_m_s: float
    created_at: dt.datetime


class MachineList(Out):
    items: list[MachineOut]
    total: int


class DeviceTokenOut(Out):
    machine_id: int
    token: str
    mqtt_username: str = Field(
        description="MQTT user name of the machine; its MQTT password is this token"
    )
    expires_at: dt.datetime | None = None
