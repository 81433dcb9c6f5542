"""Linear active disturbance rejection control (LADRC), order 1 or 2.

Seed 001 sec. 2.1.2 (eq. 5-13): the plant is treated as a chain of ``order``
integrators with high-frequency gain b0 plus a "total disturbance" f, which a
linear extended state observer (LESO) estimates as an extra state; the control
law cancels it and closes a PD (order 2) or P (order 1) loop on the estimates:

    order 2: u = (kp (r - z1) + kd (r' - z2) - z3) / b0,  kp = wc^2, kd = 2 wc
    order 1: u = (kp (r - z1) - z2) / b0,                 kp = wc

Observer discretisation. The paper's continuous LESO (beta = 3wo, 3wo^2, wo^3)
integrated by forward Euler is unstable when wo*T is large (wo 400 at 2 ms).
The default here is the discrete *current-estimator* ESO of Miklosovic, Radke
and Gao (2006, "Discrete implementation and generalization of the extended
state observer", ACC): the integrator chain is discretised exactly (ZOH) and
the observer gain is placed so all observer poles sit at z = exp(-wo T), the
exact image of the continuous bandwidth design. It is stable for every wo and
T, and it uses the current measurement (no extra sample of latency).
``observer="euler"`` keeps the paper's Euler form, to show its instability.

Anti-windup: the observer is driven by the *clamped* command, so the
disturbance estimate never winds up while the actuator is saturated.

Optional tracking differentiator (``td_r`` > 0): Han's linear TD, a critically
damped second-order reference filter with bandwidth td_r, discretised exactly;
it shapes steps into smooth references and supplies r' for order 2.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from fieldrx_edge.control.base import Controller
from fieldrx_edge.plants.linalg import zoh

_OBSERVERS = ("current", "euler")


def _chain(order: int, b0: float) -> tuple[np.ndarray, np.ndarray]:
    """Extended integrator chain: order + 1 states, input enters state ``order``."""
    m = order + 1
    a = np.diag(np.ones(m - 1), 1)
    b = np.zeros((m, 1))
    b[order - 1, 0] = b0
    return a, b


def current_estimator_gain(phi: np.ndarray, pole: float) -> np.ndarray:
    """Current-estimator gain Lc with all eigenvalues of (I - Lc C) Phi at ``pole``.

    Ackermann's formula gives the predictor gain Lp for (Phi, C); the current
    estimator's error evolves as (Phi - Phi Lc C), so Lc = Phi^-1 Lp.
    """
    m = phi.shape[0]
    c = np.zeros((1, m))
    c[0, 0] = 1.0
    obs = np.vstack([c @ np.linalg.matrix_power(phi, k) for k in range(m)])
    coeffs = np.poly(np.full(m, pole))  # (z - pole)^m, descending powers
    alpha = sum(coeffs[k] * np.linalg.matrix_power(phi, m - k) for k in range(m + 1))
    unit = np.zeros((m, 1))
    unit[-1, 0] = 1.0
    lp = alpha @ np.linalg.solve(obs, unit)
    return np.linalg.solve(phi, lp)[:, 0]


class LADRC(Controller):
    """Linear ADRC with bandwidth tuning (wc, wo, b0), order 1 or 2.

    Seed 001's parameters are order 2, wc 150, wo 400, b0 6000. For its motor,
    which is first order (docs/science.md), order 1 is the principled design; see
    bench/control.py for the design used by FieldRx.
    """

    def __init__(
        self,
        wc: float,
        wo: float,
        b0: float,
        order: int = 1,
        *,
        td_r: float = 0.0,
        observer: str = "current",
        out_min: float = -math.inf,
        out_max: float = math.inf,
    ) -> None:
        super().__init__(out_min, out_max)
        if order not in (1, 2):
            raise ValueError("order must be 1 or 2")
        if observer not in _OBSERVERS:
            raise ValueError(f"observer must be one of {_OBSERVERS}")
        self.order = order
        self.observer = observer
        self.wc = float(wc)
        self.wo = float(wo)
        self.b0 = float(b0)
        self.td_r = float(td_r)
        self._check()
        self._dt = -1.0
        self.reset()

    def _check(self) -> None:
        if self.wc <= 0 or self.wo <= 0:
            raise ValueError("wc and wo must be positive")
        if self.b0 == 0:
            raise ValueError("b0 must be non-zero")
        if self.td_r < 0:
            raise ValueError("td_r must be >= 0 (0 disables the tracking differentiator)")

    def params(self) -> dict[str, Any]:
        return {
            "wc": self.wc,
            "wo": self.wo,
            "b0": self.b0,
            "order": self.order,
            "td_r": self.td_r,
            "observer": self.observer,
        }

    def reset(self) -> None:
        self._z = [0.0] * (self.order + 1)  # predicted (a-priori) observer state
        self._v1 = 0.0  # TD: shaped reference and its derivative
        self._v2 = 0.0
        self._started = False
        self._r = 0.0
        self._y = 0.0
        self._u = 0.0

    @property
    def states(self) -> list[float]:
        """Observer estimate [y, (y'), f] after the last step's correction."""
        return list(self._zc) if self._started else list(self._z)

    def _design(self, dt: float) -> None:
        """Precompute the discrete observer and TD for period ``dt``."""
        m = self.order + 1
        self._kp = self.wc if self.order == 1 else self.wc * self.wc
        self._kd = 0.0 if self.order == 1 else 2.0 * self.wc
        if self.observer == "current":
            a, b = _chain(self.order, self.b0)
            phi, gam = zoh(a, b, dt)
            self._phi = phi.tolist()
            self._gam = [float(g) for g in gam[:, 0]]
            self._lc = [float(v) for v in current_estimator_gain(phi, math.exp(-self.wo * dt))]
        else:
            binom = [math.comb(m, k) for k in range(1, m + 1)]  # (s + wo)^m
            self._lc = [binom[k] * self.wo ** (k + 1) for k in range(m)]
        if self.td_r > 0.0:
            r = self.td_r
            phi, gam = zoh([[0.0, 1.0], [-r * r, -2.0 * r]], [[0.0], [r * r]], dt)
            self._td_phi = phi.tolist()
            self._td_gam = [float(gam[0, 0]), float(gam[1, 0])]
        self._dt = dt

    def _law(self, zc: list[float], r: float, rd: float) -> float:
        if self.order == 1:
            return (self._kp * (r - zc[0]) - zc[1]) / self.b0
        return (self._kp * (r - zc[0]) + self._kd * (rd - zc[1]) - zc[2]) / self.b0

    def _shape(self, setpoint: float) -> tuple[float, float]:
        """Advance the tracking differentiator one period; returns (r, r')."""
        if self.td_r <= 0.0:
            return setpoint, 0.0
        p = self._td_phi
        g = self._td_gam
        v1, v2 = self._v1, self._v2
        self._v1 = p[0][0] * v1 + p[0][1] * v2 + g[0] * setpoint
        self._v2 = p[1][0] * v1 + p[1][1] * v2 + g[1] * setpoint
        return v1, v2

    def set_params(self, **kw: Any) -> None:
        """Retune; the disturbance estimate absorbs the change so the command stays put."""
        self._reject_unknown(kw)
        if "out_min" in kw or "out_max" in kw:
            self.set_limits(kw.get("out_min", self.out_min), kw.get("out_max", self.out_max))
        if "order" in kw and int(kw["order"]) != self.order:
            raise ValueError("changing the observer order needs a new controller")
        if "observer" in kw and kw["observer"] not in _OBSERVERS:
            raise ValueError(f"observer must be one of {_OBSERVERS}")
        old = (self.wc, self.wo, self.b0, self.td_r, self.observer)
        target = self._u
        for key in ("wc", "wo", "b0", "td_r"):
            if key in kw:
                setattr(self, key, float(kw[key]))
        if "observer" in kw:
            self.observer = kw["observer"]
        try:
            self._check()
        except ValueError:
            self.wc, self.wo, self.b0, self.td_r, self.observer = old
            raise
        if self.td_r > 0.0 and old[3] <= 0.0:
            self._v1, self._v2 = self._r, 0.0
        if not self._started:
            self._dt = -1.0
            return
        self._design(self._dt)
        # Bumpless: the next step, with unchanged inputs, must return the last command.
        zc = self._correct(self._y)
        rd = self._v2 if self.td_r > 0.0 else 0.0
        r = self._v1 if self.td_r > 0.0 else self._r
        u_new = self._law(zc, r, rd)
        self._z[-1] += self.b0 * (u_new - target)

    def _correct(self, y: float) -> list[float]:
        z = self._z
        if self.observer == "euler":
            return list(z)
        err = y - z[0]
        lc = self._lc
        return [z[i] + lc[i] * err for i in range(len(z))]

    def step(self, setpoint: float, measurement: float, dt: float) -> float:
        # Pass the nominal loop period: the discrete observer is redesigned (numpy, ~100 us)
        # only when dt differs from the design period by more than 1 %, not on timing jitter.
        if dt != self._dt and abs(dt - self._dt) > 0.01 * self._dt:
            self._design(dt)
        if not self._started:
            self._z = [measurement] + [0.0] * self.order
            # The shaped reference starts where the plant is, so a start from rest is smooth.
            self._v1, self._v2 = measurement, 0.0
            self._started = True
        self._r = setpoint
        self._y = measurement
        r, rd = self._shape(setpoint)
        z = self._z
        if self.observer == "current":
            err = measurement - z[0]
            lc = self._lc
            if self.order == 1:
                z1 = z[0] + lc[0] * err
                z2 = z[1] + lc[1] * err
                u = self._clamp((self._kp * (r - z1) - z2) / self.b0)
                p = self._phi
                g = self._gam
                self._zc = [z1, z2]
                self._z = [z1 + p[0][1] * z2 + g[0] * u, z2]
            else:
                z1 = z[0] + lc[0] * err
                z2 = z[1] + lc[1] * err
                z3 = z[2] + lc[2] * err
                u = self._clamp((self._kp * (r - z1) + self._kd * (rd - z2) - z3) / self.b0)
                p = self._phi
                g = self._gam
                self._zc = [z1, z2, z3]
                self._z = [
                    z1 + p[0][1] * z2 + p[0][2] * z3 + g[0] * u,
                    z2 + p[1][2] * z3 + g[1] * u,
                    z3,
                ]
        else:  # forward-Euler continuous LESO, as a naive implementation would do
            err = measurement - z[0]
            lc = self._lc
            u = self._clamp(self._law(z, r, rd))
            self._zc = list(z)
            if self.order == 1:
                self._z = [z[0] + dt * (z[1] + self.b0 * u + lc[0] * err), z[1] + dt * lc[1] * err]
            else:
                self._z = [
                    z[0] + dt * (z[1] + lc[0] * err),
                    z[1] + dt * (z[2] + self.b0 * u + lc[1] * err),
                    z[2] + dt * lc[2] * err,
                ]
        self._u = u
        return u
