"""Sliding-window mean filter (seed 000 sec. 2.1: window 15 for NDVI)."""

from __future__ import annotations

import math
from collections import deque


class SlidingWindowMean:
    """Mean of the last ``window`` samples in O(1) per update.

    A running sum is kept; to stop floating-point drift over days of
    operation it is recomputed exactly (math.fsum) every ``window * 1000``
    updates, which is still O(1) amortised. Before the window fills, the mean
    is over the samples seen so far.
    """

    def __init__(self, window: int = 15) -> None:
        if window < 1:
            raise ValueError("window must be >= 1")
        self.window = int(window)
        self.reset()

    def reset(self) -> None:
        self._buf: deque[float] = deque(maxlen=self.window)
        self._sum = 0.0
        self._since_resync = 0

    def __len__(self) -> int:
        return len(self._buf)

    def update(self, x: float) -> float:
        x = float(x)
        if not math.isfinite(x):
            raise ValueError(f"sample must be finite, got {x}")
        if len(self._buf) == self.window:
            self._sum -= self._buf[0]
        self._buf.append(x)
        self._sum += x
        self._since_resync += 1
        if self._since_resync >= self.window * 1000:
            self._sum = math.fsum(self._buf)
            self._since_resync = 0
        return self._sum / len(self._buf)

    @property
    def value(self) -> float | None:
        return self._sum / len(self._buf) if self._buf else None
