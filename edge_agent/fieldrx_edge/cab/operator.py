"""The operator's hand on the meter: pause, a rate override in percent steps, sections off.

Nothing the operator does is silent: every record written while one of these is in force
carries its tag (``operator_pause``, ``operator_rate_override``, ``operator_section_off``)
so the server's report shows where and for how long the prescription was overridden, and
an override the meter cannot follow is cut to the meter's calibrated range and the screen
says so (``limited``).
"""

from __future__ import annotations

import dataclasses
import threading
from typing import Any

STEP_PCT = 5.0
MAX_OVERRIDE_PCT = 50.0


class Operator:
    """Shared between the screen (HTTP thread) and the loop; the loop reads it per fix."""

    def __init__(self, min_rpm: float, max_rpm: float, sections: int = 1) -> None:
        self.min_rpm = min_rpm
        self.max_rpm = max_rpm
        self.sections = max(1, sections)
        self.override_pct = 0.0
        self.paused = False
        self.sections_off: set[int] = set()
        self.limited = False  # the last override was cut to the meter range
        self.inner: Any = None  # the simulator's implement (ISOBUS pair) behind the operator
        self._lock = threading.Lock()

    # -- the screen's buttons --------------------------------------------

    def nudge(self, steps: int) -> float:
        """Override by ``steps`` x 5 %, within +-50 % (beyond is refused, not stored)."""
        with self._lock:
            want = self.override_pct + STEP_PCT * steps
            if abs(want) > MAX_OVERRIDE_PCT:
                raise ValueError(
                    f"rate override {want:+.0f} % is beyond +-{MAX_OVERRIDE_PCT:.0f} %"
                )
            self.override_pct = want
            return want

    def set_paused(self, paused: bool) -> None:
        self.paused = paused

    def toggle_section(self, k: int) -> bool:
        if not 0 <= k < self.sections:
            raise ValueError(f"section {k + 1}: the implement has {self.sections}")
        with self._lock:
            if k in self.sections_off:
                self.sections_off.discard(k)
                return True
            self.sections_off.add(k)
            return False

    # -- the loop's side ---------------------------------------------------

    def apply(self, target_rpm: float) -> float:
        """The shaft target the meter gets for the runtime's ``target_rpm``."""
        if target_rpm <= 0.0:
            return 0.0
        if self.paused or len(self.sections_off) >= self.sections:
            return 0.0
        share = 1.0 - len(self.sections_off) / self.sections  # a section off: its width dry
        rpm = target_rpm * (1.0 + self.override_pct / 100.0) * share
        clamped = min(self.max_rpm, max(self.min_rpm, rpm))
        self.limited = self.override_pct != 0.0 and abs(clamped - rpm) > 1e-9
        return clamped

    def step(self, t: float, d: Any, actual_rpm: float) -> float:
        """``SimConfig.implement``'s interface: the shaft target for decision ``d``."""
        base = d.target_rpm if d.metering else 0.0
        sp = self.apply(base)
        if self.inner is not None:
            scaled = dataclasses.replace(d, target_rpm=sp, metering=d.metering and sp > 0)
            return float(self.inner.step(t, scaled, actual_rpm))
        return sp

    def tag(self, rec: dict[str, Any], alarms: list[str]) -> None:
        """Add the operator's tags in force to a record's alarm list (in place)."""
        if self.paused:
            alarms.append("operator_pause")
        if self.override_pct != 0.0:
            alarms.append("operator_rate_override")
        if self.sections_off:
            alarms.append("operator_section_off")

    def to_dict(self) -> dict[str, Any]:
        return {
            "paused": self.paused,
            "override_pct": self.override_pct,
            "limited": self.limited,
            "sections": self.sections,
            "sections_off": sorted(self.sections_off),
        }


class OperatedMotor:
    """A motor loop (or ISOBUS implement) whose shaft target passes the operator first:
    ``run``'s ``Agent`` sets ``setpoint_rpm`` on it as on the motor itself."""

    def __init__(self, motor: Any, operator: Operator) -> None:
        self.motor = motor
        self.operator = operator

    @property
    def setpoint_rpm(self) -> float:
        return float(self.motor.setpoint_rpm)

    @setpoint_rpm.setter
    def setpoint_rpm(self, v: float) -> None:
        self.motor.setpoint_rpm = self.operator.apply(v)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.motor, name)
