"""Motor driver interface: simulated motor in a loop, serial driver against a pty board."""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator

import pytest
import serial
from fieldrx_edge.control import make_controller
from fieldrx_edge.plants import (
    MotorDriver,
    MotorDriverError,
    SerialMotorDriver,
    SimulatedMotor,
    seed001_motor,
)


def test_simulated_motor_in_a_duty_limited_loop() -> None:
    dt = 2e-3
    motor = SimulatedMotor(seed001_motor(dt, u_min=0.0, u_max=100.0))
    assert isinstance(motor, MotorDriver)
    ctrl = make_controller("ladrc", wc=20.0, wo=100.0, b0=8.892, out_min=0.0, out_max=100.0)
    for _ in range(500):
        motor.write_duty(ctrl.step(60.0, motor.read_rpm(), dt))
    assert motor.read_rpm() == pytest.approx(60.0, rel=1e-3)
    assert 0.0 <= motor.duty_pct <= 100.0
    assert motor.time_s == pytest.approx(1.0)


class FakeBoard:
    """Firmware stand-in on the master side of a pty: first-order motor, line protocol."""

    def __init__(self, fd: int, mode: str = "ok") -> None:
        self.fd = fd
        self.mode = mode
        self.duty = 0.0
        self.rpm = 0.0
        self.lines: list[str] = []
        self._stop = False
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self) -> None:
        buf = b""
        while not self._stop:
            try:
                chunk = os.read(self.fd, 256)
            except OSError:
                return
            buf += chunk
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                self.handle(line.decode().strip())

    def handle(self, line: str) -> None:
        self.lines.append(line)
        if self.mode == "silent":
            return
        if not line.startswith("D "):
            os.write(self.fd, b"E unknown command\n")
            return
        self.duty = float(line[2:])
        if self.duty > 90.0:
            os.write(self.fd, b"E overcurrent\n")
            return
        self.rpm += 0.5 * (1.3 * self.duty - self.rpm)
        reply = "S garbage\n" if self.mode == "garbled" else f"S {self.rpm:.3f}\n"
        os.write(self.fd, reply.encode())

    def close(self) -> None:
        self._stop = True


@pytest.fixture
def pty_pair() -> Iterator[tuple[int, str]]:
    master, slave = os.openpty()
    name = os.ttyname(slave)
    yield master, name
    os.close(master)
    os.close(slave)


def _driver(name: str) -> SerialMotorDriver:
    ser = serial.Serial(name, 115200, timeout=0.2)
    ser.reset_input_buffer()
    return SerialMotorDriver(ser, max_missed=2)


def test_serial_driver_line_protocol(pty_pair: tuple[int, str]) -> None:
    master, name = pty_pair
    board = FakeBoard(master)
    drv = _driver(name)
    assert isinstance(drv, MotorDriver)
    for _ in range(20):
        drv.write_duty(50.0)
    assert drv.read_rpm() == pytest.approx(65.0, abs=0.01)
    with pytest.raises(MotorDriverError, match="overcurrent"):
        drv.write_duty(250.0)  # clamped to 100 % before it goes on the wire
    assert board.lines[-1] == "D 100.00"
    with pytest.raises(ValueError):
        drv.write_duty(float("nan"))
    board.close()


def test_serial_driver_refusal_and_silence(pty_pair: tuple[int, str]) -> None:
    master, name = pty_pair
    board = FakeBoard(master)
    drv = _driver(name)
    with pytest.raises(MotorDriverError, match="overcurrent"):
        drv.write_duty(95.0)
    drv.write_duty(10.0)
    last = drv.read_rpm()
    board.mode = "garbled"
    drv.write_duty(10.0)  # first miss: keeps the last speed
    assert drv.read_rpm() == last and drv.missed == 1
    board.mode = "silent"
    with pytest.raises(MotorDriverError, match="2 times"):
        drv.write_duty(10.0)
    board.close()
