"""The metering-motor interface: PWM duty out (%), encoder shaft speed in (r/min).

``MotorDriver`` is what the runtime loop (``fieldrx_edge.motor``) talks to;
``SimulatedMotor`` puts a discretised plant behind it (simulation, tests),
``SerialMotorDriver`` a motor board on a serial line (real hardware). Method
names and the line protocol match ``fieldrx_edge.motor`` so either can be used.

Serial line protocol (ASCII, ``\\n`` terminated, 115200 8N1 by default):

    host -> board        board -> host
    D <duty_pct>         S <rpm>          set PWM duty (2 decimals, -100..100, sign =
                                          direction); the board answers with its
                                          latest encoder shaft speed in r/min
                         E <reason>       the board refused the command

A board that stays silent for the read timeout keeps the last speed; after
``max_missed`` consecutive silent or malformed answers ``MotorDriverError`` is
raised so the caller can stop the job rather than fly blind.
"""

from __future__ import annotations

import logging
import math
from typing import Any, Protocol, runtime_checkable

from fieldrx_edge.plants.lti import DiscretePlant

log = logging.getLogger(__name__)


class MotorDriverError(RuntimeError):
    """The motor board stopped answering, or refused a command."""


@runtime_checkable
class MotorDriver(Protocol):
    """A speed-controlled metering motor as the control loop sees it."""

    def write_duty(self, duty_pct: float) -> None:
        """Apply a PWM duty cycle in % (the controller's clamped output)."""
        ...

    def read_rpm(self) -> float:
        """Latest encoder shaft speed in r/min."""
        ...


class SimulatedMotor:
    """A ``MotorDriver`` around a ``DiscretePlant`` whose input is duty in %.

    The plant's own limits act as the actuator saturation (e.g.
    ``seed001_motor(dt, u_min=0, u_max=100)``). Time advances one plant period
    per ``write_duty``, as on hardware where the next encoder reading comes one
    loop period after the command.
    """

    def __init__(self, plant: DiscretePlant) -> None:
        self.plant = plant
        self.duty_pct = 0.0
        self.time_s = 0.0

    def write_duty(self, duty_pct: float) -> None:
        if math.isnan(duty_pct):
            raise ValueError("duty is NaN")
        self.duty_pct = float(duty_pct)
        self.plant.step(self.duty_pct)
        self.time_s += self.plant.dt

    def read_rpm(self) -> float:
        return self.plant.output


class SerialMotorDriver:
    """A ``MotorDriver`` speaking the line protocol above over pyserial.

    ``port`` is anything ``serial.serial_for_url`` accepts (``/dev/ttyUSB0``,
    ``socket://host:port``, ``rfc2217://...``), or an open serial-like object
    with ``write``, ``readline`` and ``close`` (used by the tests with a pty).
    """

    def __init__(
        self,
        port: Any,
        baudrate: int = 115200,
        timeout_s: float = 0.05,
        max_missed: int = 3,
    ) -> None:
        if isinstance(port, str):
            import serial  # pyserial, imported lazily: simulation needs no port

            self._ser = serial.serial_for_url(port, baudrate=baudrate, timeout=timeout_s)
        else:
            self._ser = port
        self.max_missed = int(max_missed)
        self.missed = 0
        self.duty_pct = 0.0
        self._rpm = 0.0

    def write_duty(self, duty_pct: float) -> None:
        if not math.isfinite(duty_pct):
            raise ValueError(f"duty must be finite, got {duty_pct}")
        d = max(-100.0, min(100.0, float(duty_pct)))
        self._ser.write(f"D {d:.2f}\n".encode("ascii"))
        self.duty_pct = d
        raw = self._ser.readline()
        reply = raw.decode("ascii", errors="replace").strip() if raw else ""
        if reply.startswith("E"):
            raise MotorDriverError(f"motor board refused duty {d:.2f}: {reply[1:].strip()}")
        rpm = self._parse_speed(reply)
        if rpm is None:
            self.missed += 1
            log.warning("motor board answer %r (%d missed in a row)", reply, self.missed)
            if self.missed >= self.max_missed:
                raise MotorDriverError(f"motor board silent or garbled {self.missed} times")
            return
        self.missed = 0
        self._rpm = rpm

    @staticmethod
    def _parse_speed(reply: str) -> float | None:
        parts = reply.split()
        if len(parts) != 2 or parts[0] != "S":
            return None
        try:
            rpm = float(parts[1])
        except ValueError:
            return None
        return rpm if math.isfinite(rpm) else None

    def read_rpm(self) -> float:
        return self._rpm

    def close(self) -> None:
        try:
            self.write_duty(0.0)
        except MotorDriverError:
            pass
        finally:
            self._ser.close()
