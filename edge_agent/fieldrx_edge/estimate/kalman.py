"""Scalar Kalman filter for GNSS ground speed, seed 001 eq. 14-15."""

from __future__ import annotations

import math


class KalmanSpeedFilter:
    """Random-walk speed model, seed 001 eq. 14-15 with A = H = 1.

    Predict: x- = x, P- = P + Q. Update: K = P- / (P- + R), x = x- + K (z - x-),
    P = (1 - K) P-. Paper values Q 0.01, R 0.2, P0 1; the gain converges to
    about 0.2. Differences from the paper, both on purpose:

    - initialised from the first measurement, not x0 = 0 (which would make the
      first estimate -100 % wrong, docs/science.md);
    - gross outliers are gated: a measurement whose innovation exceeds
      ``gate_sigma`` * sqrt(P- + R) is rejected (prediction kept). After
      ``max_rejects`` rejections in a row the filter assumes the *estimate*
      is wrong (e.g. a real sudden stop) and re-initialises from the
      measurement. ``gate_sigma=None`` disables gating.
    """

    def __init__(
        self,
        q: float = 0.01,
        r: float = 0.2,
        p0: float = 1.0,
        gate_sigma: float | None = 3.0,
        max_rejects: int = 3,
    ) -> None:
        if q < 0 or r <= 0 or p0 <= 0:
            raise ValueError("need q >= 0, r > 0, p0 > 0")
        if gate_sigma is not None and gate_sigma <= 0:
            raise ValueError("gate_sigma must be positive or None")
        if max_rejects < 1:
            raise ValueError("max_rejects must be >= 1")
        self.q = float(q)
        self.r = float(r)
        self.p0 = float(p0)
        self.gate_sigma = gate_sigma
        self.max_rejects = int(max_rejects)
        self.reset()

    def reset(self) -> None:
        self.x: float | None = None
        self.p = self.p0
        self.gain = 0.0
        self.rejects_in_row = 0
        self.rejected_total = 0
        self.last_rejected = False

    def update(self, z: float) -> float:
        """Fold in one speed measurement (m/s) and return the estimate."""
        z = float(z)
        if not math.isfinite(z):
            raise ValueError(f"speed measurement must be finite, got {z}")
        if self.x is None:
            self.x = z
            self.p = self.p0
            self.last_rejected = False
            return z
        p_pred = self.p + self.q
        s = p_pred + self.r
        innov = z - self.x
        if self.gate_sigma is not None and abs(innov) > self.gate_sigma * math.sqrt(s):
            self.rejects_in_row += 1
            self.rejected_total += 1
            self.last_rejected = True
            if self.rejects_in_row >= self.max_rejects:
                self.rejects_in_row = 0
                self.x = z
                self.p = self.p0
                return z
            self.p = p_pred  # coasting: uncertainty grows, estimate held
            return self.x
        self.rejects_in_row = 0
        self.last_rejected = False
        k = p_pred / s
        self.gain = k
        self.x += k * innov
        self.p = (1.0 - k) * p_pred
        return self.x

    @property
    def value(self) -> float | None:
        return self.x
