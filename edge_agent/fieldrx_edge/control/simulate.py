"""Closed-loop simulation of a controller on a discretised plant (tests, bench, sim).

The plant runs at its own period ``plant.dt``; the controller runs every
``ctrl_period_s`` (a whole multiple of it) and its command is held in
between, exactly as a digital controller drives a continuous plant.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from fieldrx_edge.control.base import Controller
from fieldrx_edge.plants.lti import DiscretePlant


@dataclass
class Trace:
    t: list[float] = field(default_factory=list)
    y: list[float] = field(default_factory=list)
    u: list[float] = field(default_factory=list)
    r: list[float] = field(default_factory=list)


def closed_loop(
    controller: Controller,
    plant: DiscretePlant,
    setpoint: float | Callable[[float], float],
    duration_s: float,
    *,
    ctrl_period_s: float | None = None,
    disturbance: Callable[[float], float] | None = None,
    feedback_scale: float = 1.0,
) -> Trace:
    """Simulate from the plant's present state; returns samples at the plant period.

    ``setpoint`` and ``disturbance`` may be functions of time. The controller
    sees setpoint and measurement multiplied by ``feedback_scale`` (seed 000's
    controller works on encoder volts, 1/8 V per r/min).
    """
    dt = plant.dt
    ts = dt if ctrl_period_s is None else ctrl_period_s
    ratio = int(round(ts / dt))
    if ratio < 1 or abs(ratio * dt - ts) > 1e-9 * max(1.0, ts):
        raise ValueError("controller period must be a whole multiple of the plant period")
    sp = setpoint if callable(setpoint) else (lambda _t, v=float(setpoint): v)
    n = int(round(duration_s / dt))
    tr = Trace()
    y = plant.output
    u = controller.output
    for k in range(n):
        t = k * dt
        r = sp(t)
        if disturbance is not None:
            plant.disturbance = disturbance(t)
        if k % ratio == 0:
            u = controller.step(r * feedback_scale, y * feedback_scale, ts)
        tr.t.append(t)
        tr.y.append(y)
        tr.u.append(u)
        tr.r.append(r)
        y = plant.step(u)
    tr.t.append(n * dt)
    tr.y.append(y)
    tr.u.append(u)
    tr.r.append(sp(n * dt))
    return tr


def step_at(t0: float, before: float, after: float) -> Callable[[float], float]:
    """A step signal: ``before`` until t0, ``after`` from t0 on."""

    def f(t: float) -> float:
        return after if t >= t0 - 1e-12 else before

    return f
