"""Shared closed-loop fixtures for the control tests."""

from __future__ import annotations

from fieldrx_edge.control import Controller
from fieldrx_edge.control.metrics import StepMetrics, step_metrics
from fieldrx_edge.control.simulate import Trace, closed_loop
from fieldrx_edge.plants import seed001_motor


def seed001_run(
    ctrl: Controller, dt: float, duration_s: float = 3.0, dist_at: float | None = 1.5
) -> Trace:
    """Unit step at t = 0 on seed 001's motor; optional 0.1 input step disturbance."""
    plant = seed001_motor(dt)
    dist = None if dist_at is None else (lambda t: 0.1 if t >= dist_at - 1e-12 else 0.0)
    return closed_loop(ctrl, plant, 1.0, duration_s, disturbance=dist)


def metrics_until(tr: Trace, t_end: float) -> StepMetrics:
    n = next(k for k, t in enumerate(tr.t) if t >= t_end - 1e-12)
    return step_metrics(tr.t[:n], tr.y[:n], 0.0, 1.0)
