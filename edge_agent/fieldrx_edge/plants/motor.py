"""The metering-motor interface: PWM duty out, encoder speed in.

``MotorDriver`` is what the runtime loop talks to; ``SimulatedMotor`` puts a
discretised plant behind it (simulation, tests), ``SerialMotorDriver`` a
microcontroller on a serial line (real hardware).

Serial line protocol (ASCII, one command per line, ``\\n`` terminated,
115200 8N1 by default; the firmware answers every command with one line):

    host -> device            device -> host
    D <duty>                  OK                 set PWM duty, -1.0 .. 1.0 (sign = direction)
    S?                        S <rpm>            read shaft speed in r/min (float)
    X                         OK                 stop: duty 0, brake if available
    anything else / bad value ERR <reason>

Duty is sent with 4 decimals. A missing or malformed answer within the
timeout raises ``MotorDriverError``; the caller decides to stop the job.
"""

from __future__ import annotations

import math
from typing import Protocol, runtime_checkable

from fieldrx_edge.plants.lti import DiscretePlant


class MotorDriverError(RuntimeError):
    """The motor controller did not answer, or answered with an error."""


@runtime_checkable
class MotorDriver(Protocol):
    """A speed-controlled metering motor as the control loop sees it."""

    def set_duty(self, duty: float) -> None:
        """Apply a PWM duty cycle in [-1, 1] (values outside are clamped)."""
        ...

    def read_speed_rpm(self) -> float:
        """Latest encoder shaft speed in r/min."""
        ...

    def stop(self) -> None:
        """Duty 0 immediately (end of job, fault)."""
        ...


def _clamp_duty(duty: float) -> float:
    if math.isnan(duty):
        raise ValueError("duty is NaN")
    return -1.0 if duty < -1.0 else 1.0 if duty > 1.0 else duty


class SimulatedMotor:
    """A ``MotorDriver`` around a ``DiscretePlant``.

    The plant input is ``duty * input_scale`` (e.g. 100 for seed 001, whose
    G(s) takes duty in %; 5.0 for a 0-5 V driver input). Time advances one
    plant period per ``set_duty`` call, as on hardware where the next encoder
    reading comes one loop period after the command.
    """

    def __init__(self, plant: DiscretePlant, input_scale: float = 1.0) -> None:
        self.plant = plant
        self.input_scale = float(input_scale)
        self.duty = 0.0
        self.time_s = 0.0

    def set_duty(self, duty: float) -> None:
        self.duty = _clamp_duty(float(duty))
        self.plant.step(self.duty * self.input_scale)
        self.time_s += self.plant.dt

    def read_speed_rpm(self) -> float:
        return self.plant.output

    def stop(self) -> None:
        self.duty = 0.0


class SerialMotorDriver:
    """A ``MotorDriver`` speaking the line protocol above over pyserial.

    ``port`` is anything ``serial.serial_for_url`` accepts (``/dev/ttyUSB0``,
    ``socket://host:port``, ``rfc2217://...``), or an already-open serial-like
    object with ``write``, ``readline`` and ``close``.
    """

    def __init__(
        self,
        port: object,
        baudrate: int = 115200,
        timeout_s: float = 0.05,
    ) -> None:
        if isinstance(port, str):
            import serial  # pyserial; imported lazily so simulation needs no port

            self._ser = serial.serial_for_url(port, baudrate=baudrate, timeout=timeout_s)
        else:
            self._ser = port
        self.duty = 0.0

    def _command(self, line: str) -> str:
        self._ser.write((line + "\n").encode("ascii"))  # type: ignore[attr-defined]
        raw = self._ser.readline()  # type: ignore[attr-defined]
        if not raw or not raw.endswith(b"\n"):
            raise MotorDriverError(f"no answer to {line!r} within the timeout")
        reply = raw.decode("ascii", errors="replace").strip()
        if reply.startswith("ERR"):
            raise MotorDriverError(f"device rejected {line!r}: {reply[3:].strip()}")
        return reply

    def set_duty(self, duty: float) -> None:
        d = _clamp_duty(float(duty))
        reply = self._command(f"D {d:.4f}")
        if reply != "OK":
            raise MotorDriverError(f"unexpected reply to duty command: {reply!r}")
        self.duty = d

    def read_speed_rpm(self) -> float:
        reply = self._command("S?")
        parts = reply.split()
        if len(parts) != 2 or parts[0] != "S":
            raise MotorDriverError(f"unexpected reply to speed query: {reply!r}")
        try:
            rpm = float(parts[1])
        except ValueError:
            raise MotorDriverError(f"bad speed value in {reply!r}") from None
        if not math.isfinite(rpm):
            raise MotorDriverError(f"non-finite speed in {reply!r}")
        return rpm

    def stop(self) -> None:
        self._command("X")
        self.duty = 0.0

    def close(self) -> None:
        try:
            self.stop()
        finally:
            self._ser.close()  # type: ignore[attr-defined]
