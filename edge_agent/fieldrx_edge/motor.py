"""Motor loop: the named controller drives the metering motor at a fixed rate.

The driver interface (``MotorDriver``) is PWM duty out (0..100 %), encoder
shaft speed in (r/min). ``SimulatedMotorDriver`` runs a plant model (seed 001
eq. 4 by default) one period per write; ``SerialMotorDriver`` talks a simple
line protocol to a motor board. The controller keeps running with setpoint 0
when metering stops, so restarts are bumpless.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from typing import Any, Protocol

from fieldrx_edge.control import make_controller
from fieldrx_edge.protocol import ControllerSettings

log = logging.getLogger(__name__)

# Tuning for the seed 001 motor (first order, b = 8.892, a = 6.694) when the job
# names a controller without parameters. LADRC order 1 is the principled design
# for a first-order plant (SCIENCE.md); wc sets a ~0.05 s closed-loop time constant.
DEFAULT_PARAMS: dict[str, dict[str, Any]] = {
    "ladrc": {"wc": 20.0, "wo": 80.0, "b0": 8.892, "order": 1},
    "pid": {"kp": 1.15, "ki": 15.16, "kd": 0.01},
    "incremental_pid": {"kp": 0.15, "ki": 0.32, "kd": 0.07},
    "isp": {"kp": 0.15, "ki": 0.32, "kd": 0.07},
    "fuzzy_pid": {"kp": 1.15, "ki": 15.16, "kd": 0.01},
}


class MotorDriver(Protocol):
    """Hardware boundary: PWM duty out, encoder speed in."""

    def write_duty(self, duty_pct: float) -> None: ...

    def read_rpm(self) -> float: ...


class SimulatedMotorDriver:
    """A plant model behind the driver interface; each ``write_duty`` advances one period."""

    def __init__(self, dt: float, plant: Any | None = None) -> None:
        if plant is None:
            from fieldrx_edge.plants.seeds import seed001_motor

            plant = seed001_motor(dt, u_min=0.0, u_max=100.0)
        self.plant = plant
        self._rpm = 0.0
        self.duty = 0.0

    def write_duty(self, duty_pct: float) -> None:
        self.duty = duty_pct
        self._rpm = float(self.plant.step(duty_pct))

    def read_rpm(self) -> float:
        return self._rpm


class SerialMotorDriver:
    """Motor board on a serial line: writes ``D <duty>\\n``, reads ``S <rpm>\\n`` replies.

    The board answers every duty command with its latest encoder speed; a board
    that stays silent for ``timeout_s`` reads as 0 r/min and logs a warning.
    """

    def __init__(self, port: str, baudrate: int = 115200, timeout_s: float = 0.05) -> None:
        import serial

        self._ser = serial.Serial(port, baudrate=baudrate, timeout=timeout_s)
        self._rpm = 0.0

    def write_duty(self, duty_pct: float) -> None:
        self._ser.write(f"D {duty_pct:.2f}\n".encode())
        line = self._ser.readline().decode("ascii", "replace").strip()
        if line.startswith("S "):
            try:
                self._rpm = float(line[2:])
            except ValueError:
                log.warning("motor board sent %r", line)
        elif not line:
            log.warning("motor board silent")

    def read_rpm(self) -> float:
        return self._rpm


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
