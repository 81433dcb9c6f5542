"""Motor loop: the named controller drives the metering motor at a fixed rate.

The driver interface (``plants.motor.MotorDriver``) is PWM duty out (%),
encoder shaft speed in (r/min): ``SimulatedMotor`` (a plant model, seed 001
eq. 4 by default) or ``SerialMotorDriver`` (a motor board). The controller
keeps running with setpoint 0 when metering stops, so restarts are bumpless.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from typing import Any, Protocol, runtime_checkable

from fieldrx_edge.control import make_controller
from fieldrx_edge.job_package import ControllerSettings
from fieldrx_edge.plants.motor import MotorDriver, SerialMotorDriver, SimulatedMotor
from fieldrx_edge.plants.seeds import seed001_motor

__all__ = [
    "MeteringImplement",
    "MotorDriver",
    "MotorLoop",
    "SerialMotorDriver",
    "SimulatedMotor",
    "build_controller",
    "closed_loop_t50_s",
    "simulated_motor",
]

log = logging.getLogger(__name__)

# Tuning for the seed 001 motor (first order, b = 8.892, a = 6.694) when the job
# names a controller without parameters. LADRC order 1 is the principled design
# for a first-order plant (docs/science.md); the values are bench/control.py's
# LADRC_DESIGN (wc 20 rad/s: ~0.05 s closed-loop time constant, wo = 5 wc).
DEFAULT_PARAMS: dict[str, dict[str, Any]] = {
    "ladrc": {"wc": 20.0, "wo": 100.0, "b0": 8.892, "order": 1},
    "pid": {"kp": 1.15, "ki": 15.16, "kd": 0.01},
    "incremental_pid": {"kp": 0.15, "ki": 0.32, "kd": 0.07},
    "isp": {"kp": 0.15, "ki": 0.32, "kd": 0.07},
    "fuzzy_pid": {"kp": 1.15, "ki": 15.16, "kd": 0.01},
}


@runtime_checkable
class MeteringImplement(Protocol):
    """What the runtime's ``Agent`` drives: a ``MotorLoop`` here, or an implement behind
    ISOBUS (``isobus.implement.IsobusImplement``). ``setpoint_rpm`` is written and
    ``rpm``/``duty`` read at every fix; ``run`` is the implement's own thread. An
    implement that also has ``on_decision(decision)`` receives the whole decision (rate,
    metering on/off, speed) and may add alarms to it before the record is made."""

    setpoint_rpm: float
    rpm: float
    duty: float

    def run(self, stop: threading.Event) -> None: ...


def simulated_motor(dt: float) -> SimulatedMotor:
    """The seed 001 motor (eq. 4) behind the driver interface, duty 0..100 %."""
    return SimulatedMotor(seed001_motor(dt, u_min=0.0, u_max=100.0))


def build_controller(settings: ControllerSettings) -> Any:
    """Controller named in the job, duty limited to 0..100 %."""
    name = settings.name.strip().lower()
    params = dict(DEFAULT_PARAMS.get(name, {}))
    params.update(settings.params or {})
    params.setdefault("out_min", 0.0)
    params.setdefault("out_max", 100.0)
    return make_controller(name, **params)


class MotorLoop:
    """Fixed-rate loop: read encoder, controller step, write duty."""

    def __init__(self, controller: Any, driver: MotorDriver, period_s: float = 0.01) -> None:
        self.controller = controller
        self.driver = driver
        self.period_s = period_s
        self.setpoint_rpm = 0.0
        self.rpm = 0.0
        self.duty = 0.0
        self.overruns = 0

    def step(self) -> float:
        meas = self.driver.read_rpm()
        u = self.controller.step(self.setpoint_rpm, meas, self.period_s)
        if not math.isfinite(u):
            u = 0.0
        self.driver.write_duty(u)
        self.duty = u
        self.rpm = self.driver.read_rpm()
        return self.rpm

    def run(self, stop: threading.Event) -> None:
        """Real-time loop on the monotonic clock (no drift; overruns counted, not accumulated)."""
        nxt = time.monotonic()
        while not stop.is_set():
            self.step()
            nxt += self.period_s
            delay = nxt - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            else:
                self.overruns += 1
                nxt = time.monotonic()
        self.setpoint_rpm = 0.0
        self.driver.write_duty(0.0)


def closed_loop_t50_s(
    settings: ControllerSettings, dt: float = 0.01, r0: float = 90.0, r1: float = 100.0
) -> float:
    """Time for the controlled seed 001 motor to cover half of a setpoint step r0 -> r1.

    Added to the look-ahead so the shaft speed is half-way through a change
    when the landing point crosses a cell border (residual lag ~0). Measured on
    the plant model with the job's controller; the same model the simulator uses.
    """
    ctrl = build_controller(settings)
    plant = seed001_motor(dt, u_min=0.0, u_max=100.0)
    y = 0.0
    for _ in range(int(3.0 / dt)):  # settle at r0
        y = plant.step(ctrl.step(r0, y, dt))
    k = 0
    prev = y
    while k < int(2.0 / dt):
        y = plant.step(ctrl.step(r1, y, dt))
        k += 1
        if (y - 0.5 * (r0 + r1)) * (r1 - r0) >= 0:
            frac = (0.5 * (r0 + r1) - prev) / (y - prev) if y != prev else 1.0
            return (k - 1 + frac) * dt
        prev = y
    return 2.0
