"""Discrete SISO plant with actuator saturation, input disturbance and dead time.

The continuous model is discretised once (exact ZOH, see ``linalg.zoh``) at the
simulation period; ``step()`` then runs in plain Python floats so that long
simulations stay fast. Signal path, per sample::

    u_cmd -> clamp(u_min, u_max) -> + disturbance -> dead time -> G -> y
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from numpy.typing import ArrayLike

from fieldrx_edge.plants.linalg import tf2ss, zoh

# the continuous model's (A, B, C, D) matrices, as ``linalg.tf2ss`` returns them
StateSpace = tuple[ArrayLike, ArrayLike, ArrayLike, ArrayLike]


class DiscretePlant:
    """Exact ZOH discretisation of a continuous LTI plant ``abcd``, stepped in pure Python.

    ``delay_s`` is rounded to a whole number of samples (choose ``dt`` so that
    it divides the dead time; a ValueError is raised if it is off by more than
    1 % of a sample). ``disturbance`` is an additive input (load) disturbance in
    actuator units, applied after the saturation as a real load would be.
    """

    def __init__(
        self,
        abcd: StateSpace,
        dt: float,
        *,
        u_min: float = -math.inf,
        u_max: float = math.inf,
        delay_s: float = 0.0,
        name: str = "plant",
    ) -> None:
        if u_min > u_max:
            raise ValueError("u_min must be <= u_max")
        a, b, c, d = abcd
        am = np.atleast_2d(np.array(a, dtype=float))
        phi, gamma = zoh(am, b, dt)
        self.name = name
        self.dt = float(dt)
        self.u_min = float(u_min)
        self.u_max = float(u_max)
        self.disturbance = 0.0
        self._phi = phi.tolist()
        self._gamma = [float(g) for g in gamma[:, 0]]
        self._c = [float(v) for v in np.array(c, dtype=float).reshape(-1)]
        self._d = float(np.array(d, dtype=float).reshape(-1)[0])
        self._n = len(self._gamma)
        samples = delay_s / dt
        self.delay_samples = int(round(samples))
        if abs(samples - self.delay_samples) > 0.01:
            raise ValueError(f"dead time {delay_s} s is not a whole number of {dt} s samples")
        self._x = [0.0] * self._n
        self._buf: deque[float] = deque([0.0] * self.delay_samples)
        self._u_applied = 0.0

    @classmethod
    def from_tf(
        cls,
        num: ArrayLike,
        den: ArrayLike,
        dt: float,
        **kw: float | str,
    ) -> DiscretePlant:
        """Build from transfer-function coefficients (descending powers of s)."""
        return cls(tf2ss(num, den), dt, **kw)  # type: ignore[arg-type]

    @property
    def output(self) -> float:
        """Current output y(k) (strictly proper plants: no feedthrough of the next input)."""
        y = self._d * self._u_applied
        for ci, xi in zip(self._c, self._x, strict=True):
            y += ci * xi
        return y

    @property
    def state(self) -> list[float]:
        return list(self._x)

    def reset(self, y0: float = 0.0, u0: float | None = None) -> None:
        """Reset to rest, or to the equilibrium that holds output ``y0``.

        The equilibrium input is y0 / DC gain; it also fills the dead-time
        buffer, so a simulation can start from steady state (seed 000 starts
        at 8 r/min).
        """
        if y0 == 0.0 and u0 is None:
            self._x = [0.0] * self._n
            self._buf = deque([0.0] * self.delay_samples)
            self._u_applied = 0.0
            return
        gain = self.dc_gain()
        u_eq = y0 / gain if u0 is None else u0
        phi = np.array(self._phi)
        gam = np.array(self._gamma)
        x = np.linalg.solve(np.eye(self._n) - phi, gam * u_eq)
        self._x = [float(v) for v in x]
        self._buf = deque([u_eq] * self.delay_samples)
        self._u_applied = u_eq

    def equilibrium_input(self, y: float) -> float:
        """Plant input (before disturbance) that holds output ``y`` at steady state."""
        return y / self.dc_gain()

    def dc_gain(self) -> float:
        phi = np.array(self._phi)
        gam = np.array(self._gamma)
        x = np.linalg.solve(np.eye(self._n) - phi, gam)
        return float(np.dot(self._c, x) + self._d)

    def step(self, u: float) -> float:
        """Hold command ``u`` for one period; return the output at the end of it."""
        if u > self.u_max:
            u = self.u_max
        elif u < self.u_min:
            u = self.u_min
        u += self.disturbance
        if self.delay_samples:
            self._buf.append(u)
            u = self._buf.popleft()
        self._u_applied = u
        x = self._x
        phi = self._phi
        g = self._gamma
        n = self._n
        self._x = [sum(phi[i][j] * x[j] for j in range(n)) + g[i] * u for i in range(n)]
        return self.output
