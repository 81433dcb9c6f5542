"""Self-tuning fuzzy PID, seed 002 sec. 2.3 (eq. 10-12, Table 2).

Inputs: error e = r - y and its rate ec = de/dt, quantised by k_e, k_ec onto
[-6, 6] (clamped) and fuzzified by seven evenly spaced triangular sets
NB NM NS ZE PS PM PB (centres -6, -4, ..., 6). Mamdani inference with min
implication, MAX aggregation (seed 002 eq. 11 prints min, an erratum, see
docs/science.md) and centroid defuzzification (eq. 12) over seven triangular
output sets on [-3, 3] (centres -3, -2, ..., 3). The crisp outputs are scaled
by the output factors (Table 2) and added to the base gains: K = K' + dK
(eq. 10).

Rule tables: the paper does not print them. We use the standard textbook
dKp / dKi / dKd tables of LIU Jinkun, "Advanced PID Control and MATLAB
Simulation" (先进PID控制MATLAB仿真), 2nd ed., Publishing House of Electronics
Industry, 2004, fuzzy self-tuning PID chapter -- the tables most Chinese
agricultural-machinery papers (seed 002's refs 29-30 among them) reuse.

Speed: the Mamdani surface is computed once per table with numpy on a grid
over (E, Ec) and stored as pure-Python lists; ``step`` does a bilinear
interpolation, so it costs microseconds instead of a full inference.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Any

import numpy as np

from fieldrx_edge.control.base import Controller

NB, NM, NS, ZE, PS, PM, PB = range(-3, 4)

# Rows: E = NB..PB; columns: Ec = NB..PB. Entries are output-set indices -3..3.
RULES_DKP: tuple[tuple[int, ...], ...] = (
    (PB, PB, PM, PM, PS, ZE, ZE),
    (PB, PB, PM, PS, PS, ZE, NS),
    (PM, PM, PM, PS, ZE, NS, NS),
    (PM, PM, PS, ZE, NS, NM, NM),
    (PS, PS, ZE, NS, NS, NM, NM),
    (PS, ZE, NS, NM, NM, NM, NB),
    (ZE, ZE, NM, NM, NM, NB, NB),
)
RULES_DKI: tuple[tuple[int, ...], ...] = (
    (NB, NB, NM, NM, NS, ZE, ZE),
    (NB, NB, NM, NS, NS, ZE, ZE),
    (NB, NM, NS, NS, ZE, PS, PS),
    (NM, NM, NS, ZE, PS, PM, PM),
    (NM, NS, ZE, PS, PS, PM, PB),
    (ZE, ZE, PS, PS, PM, PB, PB),
    (ZE, ZE, PS, PM, PM, PB, PB),
)
RULES_DKD: tuple[tuple[int, ...], ...] = (
    (PS, NS, NB, NB, NB, NM, PS),
    (PS, NS, NB, NM, NM, NS, ZE),
    (ZE, NS, NM, NM, NS, NS, ZE),
    (ZE, NS, NS, NS, NS, NS, ZE),
    (ZE, ZE, ZE, ZE, ZE, ZE, ZE),
    (PB, NS, PS, PS, PS, PS, PB),
    (PB, PM, PM, PM, PS, PS, PB),
)

IN_RANGE = 6.0  # quantised input universe [-6, 6]
OUT_RANGE = 3.0  # quantised output universe [-3, 3]


def _tri(x: np.ndarray, centre: float, half_width: float) -> np.ndarray:
    return np.maximum(0.0, 1.0 - np.abs(x - centre) / half_width)


def mamdani(
    rules: tuple[tuple[int, ...], ...],
    e: np.ndarray,
    ec: np.ndarray,
    out_points: int = 601,
) -> np.ndarray:
    """Exact Mamdani inference (min, MAX, centroid) at quantised inputs ``e``, ``ec``.

    ``e`` and ``ec`` are equal-shape arrays in [-6, 6]; returns dK in [-3, 3].
    The centroid is taken over ``out_points`` samples of the output universe.
    """
    e = np.clip(np.asarray(e, dtype=float).ravel(), -IN_RANGE, IN_RANGE)
    ec = np.clip(np.asarray(ec, dtype=float).ravel(), -IN_RANGE, IN_RANGE)
    u = np.linspace(-OUT_RANGE, OUT_RANGE, out_points)
    out_sets = [_tri(u, float(k), 1.0) for k in range(-3, 4)]
    mu_e = [_tri(e, -6.0 + 2.0 * i, 2.0) for i in range(7)]
    mu_ec = [_tri(ec, -6.0 + 2.0 * j, 2.0) for j in range(7)]
    agg = np.zeros((e.size, out_points))
    for i in range(7):
        for j in range(7):
            w = np.minimum(mu_e[i], mu_ec[j])
            if not w.any():
                continue
            clipped = np.minimum(w[:, None], out_sets[rules[i][j] + 3][None, :])
            np.maximum(agg, clipped, out=agg)
    den = agg.sum(axis=1)
    num = agg @ u
    return np.where(den > 0.0, num / np.where(den > 0.0, den, 1.0), 0.0)


@lru_cache(maxsize=16)
def surface(
    rules: tuple[tuple[int, ...], ...], step: float = 0.25
) -> tuple[tuple[float, ...], ...]:
    """Mamdani surface on a (E, Ec) grid with spacing ``step`` over [-6, 6]^2.

    Returned as rows over E of tuples over Ec, plain floats, for fast lookup.
    """
    n = int(round(2 * IN_RANGE / step))
    if abs(n * step - 2 * IN_RANGE) > 1e-9:
        raise ValueError("grid step must divide 12")
    g = np.linspace(-IN_RANGE, IN_RANGE, n + 1)
    ee, cc = np.meshgrid(g, g, indexing="ij")
    z = mamdani(rules, ee, cc).reshape(ee.shape)
    return tuple(tuple(float(v) for v in row) for row in z)


class FuzzyPID(Controller):
    """PID whose gains are retuned every step by fuzzy inference (seed 002).

    Base gains ``kp, ki, kd`` (K'), quantisation factors ``k_e``, ``k_ec``
    (Table 2: 0.03, 0.12) and output factors ``k_dkp``, ``k_dki``, ``k_dkd``
    (Table 2: 0.30, 0.02, 0.5). The PID is positional with forward-Euler
    integral of Ki*e (so Ki changes never bump) and derivative Kd * ec, where
    ec is the backward difference of e, or with coefficient ``n`` the filtered
    derivative N s / (s + N) discretised exactly as ``PID`` does it: with all
    output factors 0 (dK = 0) it is ``PID`` with the same gains, sample for
    sample, so a comparison with the fixed PID differs only by the adaptation.
    The filtered ec is also the fuzzy input Ec. Gains never go below zero. Anti-windup: conditional
    integration, as in ``PID``.
    """

    def __init__(
        self,
        kp: float,
        ki: float,
        kd: float,
        *,
        k_e: float = 0.03,
        k_ec: float = 0.12,
        k_dkp: float = 0.30,
        k_dki: float = 0.02,
        k_dkd: float = 0.5,
        n: float | None = None,
        grid_step: float = 0.25,
        out_min: float = -math.inf,
        out_max: float = math.inf,
    ) -> None:
        super().__init__(out_min, out_max)
        self.kp = float(kp)
        self.ki = float(ki)
        self.kd = float(kd)
        self.k_e = float(k_e)
        self.k_ec = float(k_ec)
        self.k_dkp = float(k_dkp)
        self.k_dki = float(k_dki)
        self.k_dkd = float(k_dkd)
        self.n = None if n is None else float(n)
        self.grid_step = float(grid_step)
        self._tables = (
            surface(RULES_DKP, self.grid_step),
            surface(RULES_DKI, self.grid_step),
            surface(RULES_DKD, self.grid_step),
        )
        self._cells = len(self._tables[0]) - 1
        self._inv_step = 1.0 / self.grid_step
        self._alpha_dt = -1.0
        self._alpha = 1.0
        self.reset()

    def reset(self) -> None:
        self._integ = 0.0
        self._e = 0.0
        self._ecf = 0.0
        self._u = 0.0
        self.gains = (self.kp, self.ki, self.kd)

    def params(self) -> dict[str, Any]:
        return {
            "kp": self.kp,
            "ki": self.ki,
            "kd": self.kd,
            "k_e": self.k_e,
            "k_ec": self.k_ec,
            "k_dkp": self.k_dkp,
            "k_dki": self.k_dki,
            "k_dkd": self.k_dkd,
            "n": self.n,
        }

    def deltas(self, e: float, ec: float) -> tuple[float, float, float]:
        """(dKp, dKi, dKd) in engineering units for error ``e`` and rate ``ec``."""
        x = self.k_e * e
        y = self.k_ec * ec
        x = -IN_RANGE if x < -IN_RANGE else IN_RANGE if x > IN_RANGE else x
        y = -IN_RANGE if y < -IN_RANGE else IN_RANGE if y > IN_RANGE else y
        fx = (x + IN_RANGE) * self._inv_step
        fy = (y + IN_RANGE) * self._inv_step
        i = int(fx)
        j = int(fy)
        if i >= self._cells:
            i = self._cells - 1
        if j >= self._cells:
            j = self._cells - 1
        tx = fx - i
        ty = fy - j
        w00 = (1.0 - tx) * (1.0 - ty)
        w01 = (1.0 - tx) * ty
        w10 = tx * (1.0 - ty)
        w11 = tx * ty
        out = []
        for tab in self._tables:
            r0 = tab[i]
            r1 = tab[i + 1]
            out.append(w00 * r0[j] + w01 * r0[j + 1] + w10 * r1[j] + w11 * r1[j + 1])
        return out[0] * self.k_dkp, out[1] * self.k_dki, out[2] * self.k_dkd

    def _next_pd(self) -> float:
        kp, _, kd = self.gains
        return kp * self._e + kd * self._ecf

    def set_params(self, **kw: Any) -> None:
        """Change base gains or factors; the integrator absorbs any jump in P + D."""
        self._reject_unknown(kw)
        if "out_min" in kw or "out_max" in kw:
            self.set_limits(kw.get("out_min", self.out_min), kw.get("out_max", self.out_max))
        before = self._next_pd()
        for key in ("kp", "ki", "kd", "k_e", "k_ec", "k_dkp", "k_dki", "k_dkd"):
            if key in kw:
                setattr(self, key, float(kw[key]))
        if "n" in kw:
            self.n = None if kw["n"] is None else float(kw["n"])
            self._alpha_dt = -1.0
        dkp, dki, dkd = self.deltas(self._e, self._ecf)
        self.gains = (max(0.0, self.kp + dkp), max(0.0, self.ki + dki), max(0.0, self.kd + dkd))
        self._integ += before - self._next_pd()

    def step(self, setpoint: float, measurement: float, dt: float) -> float:
        e = setpoint - measurement
        if self.n is None:
            ec = (e - self._e) / dt
        else:
            # N s / (s + N) on e, discretised exactly as ``PID``'s derivative filter:
            # ec(k) = e^(-N dt) ec(k-1) + N (e(k) - e(k-1)), so with dK = 0 this is ``PID``.
            if dt != self._alpha_dt:
                self._alpha = 1.0 - math.exp(-self.n * dt)
                self._alpha_dt = dt
            ec = (1.0 - self._alpha) * self._ecf + self.n * (e - self._e)
        self._e = e
        self._ecf = ec
        dkp, dki, dkd = self.deltas(e, ec)
        kp = self.kp + dkp
        ki = self.ki + dki
        kd = self.kd + dkd
        kp = kp if kp > 0.0 else 0.0
        ki = ki if ki > 0.0 else 0.0
        kd = kd if kd > 0.0 else 0.0
        self.gains = (kp, ki, kd)
        u = kp * e + self._integ + kd * ec
        di = ki * e * dt
        return self._conditional_integration(u, di)
