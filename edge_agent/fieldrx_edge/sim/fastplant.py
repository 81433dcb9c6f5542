"""The seed 001 motor (eq. 4) discretised exactly like ``plants.DiscretePlant``, unrolled.

A 20 ha field is ~6 million motor periods; the generic n-state plant step is
the simulator's largest cost, so the two-state case is written out by hand.
Same ZOH (``plants.linalg``), same clamp order; a test checks equality.
"""

from __future__ import annotations

import numpy as np
from fieldrx_edge.plants.linalg import tf2ss, zoh
from fieldrx_edge.plants.seeds import SEED001_DEN, SEED001_NUM


class FastPlant2:
    def __init__(
        self,
        dt: float,
        num: tuple[float, ...] = SEED001_NUM,
        den: tuple[float, ...] = SEED001_DEN,
        u_min: float = 0.0,
        u_max: float = 100.0,
    ) -> None:
        a, b, c, d = tf2ss(num, den)
        phi, gam = zoh(np.atleast_2d(np.array(a, dtype=float)), b, dt)
        if phi.shape != (2, 2):
            raise ValueError("FastPlant2 needs a second-order plant")
        self.p00, self.p01 = float(phi[0, 0]), float(phi[0, 1])
        self.p10, self.p11 = float(phi[1, 0]), float(phi[1, 1])
        self.g0, self.g1 = float(gam[0, 0]), float(gam[1, 0])
        cc = np.array(c, dtype=float).reshape(-1)
        self.c0, self.c1 = float(cc[0]), float(cc[1])
        self.d = float(np.array(d, dtype=float).reshape(-1)[0])
        self.u_min, self.u_max = u_min, u_max
        self.x0 = self.x1 = 0.0
        self.u = 0.0

    def step(self, u: float) -> float:
        if u > self.u_max:
            u = self.u_max
        elif u < self.u_min:
            u = self.u_min
        x0, x1 = self.x0, self.x1
        self.x0 = self.p00 * x0 + self.p01 * x1 + self.g0 * u
        self.x1 = self.p10 * x0 + self.p11 * x1 + self.g1 * u
        self.u = u
        return self.c0 * self.x0 + self.c1 * self.x1 + self.d * u
