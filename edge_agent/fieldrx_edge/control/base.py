"""The one interface every loop controller implements.

Runtime code (metering motor, depth loop) only sees ``Controller``: it can swap
PID for LADRC from the job package's control settings without other changes.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import Any


class Controller(ABC):
    """SISO discrete-time controller with output limits.

    ``step(setpoint, measurement, dt)`` is called once per loop period and
    returns the actuator command, already clamped to [out_min, out_max].
    Every implementation prevents integrator wind-up while clamped, and
    ``set_params`` changes gains without a bump in the output.
    """

    def __init__(self, out_min: float = -math.inf, out_max: float = math.inf) -> None:
        self._check_limits(out_min, out_max)
        self.out_min = float(out_min)
        self.out_max = float(out_max)
        self._u = 0.0
        self._integ = 0.0

    @staticmethod
    def _check_limits(out_min: float, out_max: float) -> None:
        if not out_min <= out_max:
            raise ValueError(f"out_min {out_min} must be <= out_max {out_max}")

    @property
    def output(self) -> float:
        """The last command returned by ``step``."""
        return self._u

    def set_limits(self, out_min: float, out_max: float) -> None:
        self._check_limits(out_min, out_max)
        self.out_min = float(out_min)
        self.out_max = float(out_max)

    def _clamp(self, u: float) -> float:
        if u > self.out_max:
            return self.out_max
        if u < self.out_min:
            return self.out_min
        return u

    def _conditional_integration(self, u: float, di: float) -> float:
        """Clamp ``u`` and add the integral increment ``di`` only when it does not push
        further into the limit (conditional integration, the anti-windup of the positional
        PID and the fuzzy PID). Returns the clamped command and remembers it."""
        if u > self.out_max:
            u = self.out_max
            if di < 0.0:
                self._integ += di
        elif u < self.out_min:
            u = self.out_min
            if di > 0.0:
                self._integ += di
        else:
            self._integ += di
        self._u = u
        return u

    @abstractmethod
    def reset(self) -> None:
        """Forget all history: the next step starts from rest."""

    @abstractmethod
    def step(self, setpoint: float, measurement: float, dt: float) -> float:
        """Advance one period of ``dt`` seconds and return the clamped command."""

    @abstractmethod
    def params(self) -> dict[str, Any]:
        """Current tuning parameters (what ``set_params`` accepts)."""

    @abstractmethod
    def set_params(self, **kw: Any) -> None:
        """Change tuning parameters; the next output continues from the last one."""

    def _reject_unknown(self, kw: dict[str, Any]) -> None:
        unknown = set(kw) - set(self.params()) - {"out_min", "out_max"}
        if unknown:
            raise TypeError(f"unknown parameter(s) for {type(self).__name__}: {sorted(unknown)}")
