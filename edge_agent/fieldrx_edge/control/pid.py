"""Positional PID (Simulink-style) and the incremental PID of seed 000.

Both run on plain Python floats: one ``step`` must cost well under 20 us.
"""

from __future__ import annotations

import math
from typing import Any

from fieldrx_edge.control.base import Controller

_DERIVATIVE_ON = ("error", "measurement")
_SEPARATION_RULES = ("relative_change", "error_band", "none")


class PID(Controller):
    """Positional PID, parallel form, with a first-order derivative filter.

    C(s) = Kp + Ki / s + Kd N s / (s + N), as Simulink's PID block (seed 001
    uses Kp 1.15, Ki 15.16, Kd 0.01). The derivative acts on the error (as
    Simulink) or on the negated measurement (no kick on setpoint steps). The
    filter is discretised exactly for a held input (pole e^(-N dt)), so it is
    stable for any N and dt; ``n=None`` means an unfiltered backward
    difference. The integral is forward Euler of Ki*e, so changing Ki never
    bumps the output; anti-windup is conditional integration (the integrator
    does not move further into a limit the output is clamped at).
    """

    def __init__(
        self,
        kp: float,
        ki: float = 0.0,
        kd: float = 0.0,
        n: float | None = 100.0,
        *,
        derivative_on: str = "error",
        out_min: float = -math.inf,
        out_max: float = math.inf,
    ) -> None:
        super().__init__(out_min, out_max)
        if derivative_on not in _DERIVATIVE_ON:
            raise ValueError(f"derivative_on must be one of {_DERIVATIVE_ON}")
        if n is not None and n <= 0:
            raise ValueError("filter coefficient n must be positive (or None)")
        self.kp = float(kp)
        self.ki = float(ki)
        self.kd = float(kd)
        self.n = None if n is None else float(n)
        self.derivative_on = derivative_on
        self._alpha_dt = -1.0
        self._alpha = 0.0
        self.reset()

    def reset(self) -> None:
        self._integ = 0.0
        self._filt = 0.0  # low-passed derivative signal (error, or -measurement)
        self._sig = 0.0  # last derivative signal
        self._e = 0.0
        self._started = False
        self._reseed = False  # derivative signal switched: restart the filter without a kick
        self._u = 0.0

    @property
    def integral(self) -> float:
        """The integral term's present contribution to the output."""
        return self._integ

    def params(self) -> dict[str, Any]:
        return {
            "kp": self.kp,
            "ki": self.ki,
            "kd": self.kd,
            "n": self.n,
            "derivative_on": self.derivative_on,
        }

    def _next_pd(self) -> float:
        """P + D the next step would add if the inputs did not change."""
        if self.n is None or self._reseed:
            d = 0.0  # backward difference of an unchanged signal, or a re-seeded filter
        else:
            d = self.kd * self.n * (self._sig - self._filt)
        return self.kp * self._e + d

    def set_params(self, **kw: Any) -> None:
        """Change gains bumplessly: the integrator absorbs the jump in P + D."""
        self._reject_unknown(kw)
        before = self._next_pd()
        if "derivative_on" in kw and kw["derivative_on"] not in _DERIVATIVE_ON:
            raise ValueError(f"derivative_on must be one of {_DERIVATIVE_ON}")
        if kw.get("n", 1.0) is not None and kw.get("n", 1.0) <= 0:
            raise ValueError("filter coefficient n must be positive (or None)")
        if "out_min" in kw or "out_max" in kw:
            self.set_limits(kw.get("out_min", self.out_min), kw.get("out_max", self.out_max))
        for key in ("kp", "ki", "kd"):
            if key in kw:
                setattr(self, key, float(kw[key]))
        if "n" in kw:
            self.n = None if kw["n"] is None else float(kw["n"])
            self._alpha_dt = -1.0
        if "derivative_on" in kw and kw["derivative_on"] != self.derivative_on:
            self.derivative_on = kw["derivative_on"]
            self._reseed = self._started
        if self._started:
            self._integ += before - self._next_pd()

    def step(self, setpoint: float, measurement: float, dt: float) -> float:
        e = setpoint - measurement
        sig = e if self.derivative_on == "error" else -measurement
        if not self._started:
            # From rest: the error history is zero (Simulink's initial condition);
            # a measurement history is the first measurement (no kick).
            self._filt = self._sig = 0.0 if self.derivative_on == "error" else sig
            self._started = True
        elif self._reseed:
            self._filt = self._sig = sig
            self._reseed = False
        n = self.n
        if n is None:
            d = self.kd * (sig - self._sig) / dt
        else:
            if dt != self._alpha_dt:
                self._alpha = 1.0 - math.exp(-n * dt)
                self._alpha_dt = dt
            d = self.kd * n * (sig - self._filt)
            self._filt += self._alpha * (sig - self._filt)
        self._sig = sig
        self._e = e
        u = self.kp * e + self._integ + d
        di = self.ki * e * dt
        return self._conditional_integration(u, di)


class IncrementalPID(Controller):
    """Incremental (velocity-form) PID with integral separation, seed 000 eq. 11-12.

    dU(k) = Kp (e(k) - e(k-1)) + beta Ki e(k) + Kd (e(k) - 2 e(k-1) + e(k-2)),
    U(k) = clamp(U(k-1) + dU(k)). Gains are per sample, exactly as in eq. 11,
    so their meaning is tied to the loop period (``dt`` is not used).

    ``rule`` selects beta:
    - ``relative_change`` (seed 000 eq. 12): beta = 1 when
      |(e(k) - e(k-1)) / e(k)| <= eps. It cuts the integral on the sample of a
      setpoint jump and around zero crossings of the error.
    - ``error_band`` (textbook): beta = 1 when |e(k)| <= eps; eps is then an
      error band in measurement units.
    - ``none``: plain incremental PID (beta = 1).

    The state is the clamped output itself, so there is no wind-up and a gain
    change never bumps the output.
    """

    def __init__(
        self,
        kp: float = 0.15,
        ki: float = 0.32,
        kd: float = 0.07,
        eps: float = 0.7,
        rule: str = "relative_change",
        *,
        u0: float = 0.0,
        out_min: float = -math.inf,
        out_max: float = math.inf,
    ) -> None:
        super().__init__(out_min, out_max)
        if rule not in _SEPARATION_RULES:
            raise ValueError(f"rule must be one of {_SEPARATION_RULES}")
        self.kp = float(kp)
        self.ki = float(ki)
        self.kd = float(kd)
        self.eps = float(eps)
        self.rule = rule
        self.u0 = float(u0)
        self.reset()

    def reset(self) -> None:
        self._e1 = 0.0
        self._e2 = 0.0
        self._u = self._clamp(self.u0)
        self.integrating = False

    def params(self) -> dict[str, Any]:
        return {
            "kp": self.kp,
            "ki": self.ki,
            "kd": self.kd,
            "eps": self.eps,
            "rule": self.rule,
            "u0": self.u0,
        }

    def set_params(self, **kw: Any) -> None:
        self._reject_unknown(kw)
        if "rule" in kw and kw["rule"] not in _SEPARATION_RULES:
            raise ValueError(f"rule must be one of {_SEPARATION_RULES}")
        if "out_min" in kw or "out_max" in kw:
            self.set_limits(kw.get("out_min", self.out_min), kw.get("out_max", self.out_max))
        for key in ("kp", "ki", "kd", "eps", "u0"):
            if key in kw:
                setattr(self, key, float(kw[key]))
        if "rule" in kw:
            self.rule = kw["rule"]

    def warm_start(self, u: float, error: float = 0.0) -> None:
        """Start from a held output (e.g. the steady state before a setpoint step)."""
        self._u = self._clamp(float(u))
        self._e1 = self._e2 = float(error)

    def step(self, setpoint: float, measurement: float, dt: float) -> float:
        e = setpoint - measurement
        e1 = self._e1
        rule = self.rule
        if rule == "relative_change":
            beta = e != 0.0 and abs((e - e1) / e) <= self.eps
        elif rule == "error_band":
            beta = abs(e) <= self.eps
        else:
            beta = True
        du = self.kp * (e - e1) + self.kd * (e - 2.0 * e1 + self._e2)
        if beta:
            du += self.ki * e
        self.integrating = bool(beta)
        self._e2 = e1
        self._e1 = e
        u = self._clamp(self._u + du)
        self._u = u
        return u
