"""Where NMEA lines come from: serial port, TCP client, UDP, or a recorded file.

Every source is an iterator of text lines. Network and serial sources
reconnect on their own: a dropped cable must look like a loss of fix (the
runtime's policy handles it), not like a crash.
"""

from __future__ import annotations

import logging
import socket
import time
from collections.abc import Iterator
from pathlib import Path

log = logging.getLogger(__name__)


def _tod(line: str) -> float | None:
    """UTC time of day of an RMC/GGA/GNS line, for paced replay (after any binary prefix)."""
    start = line.find("$")
    if start > 0:
        line = line[start:]
    if len(line) < 14 or line[3:6] not in ("RMC", "GGA", "GNS"):
        return None
    field = line[7:17].split(",", 1)[0]
    try:
        return int(field[0:2]) * 3600 + int(field[2:4]) * 60 + float(field[4:])
    except ValueError:
        return None


def file_lines(path: str | Path, speed: float | None = None) -> Iterator[str]:
    """Replay a log. ``speed`` None: as fast as possible; 1.0: recorded pace; k: k times faster.

    Pacing follows the NMEA time field of RMC/GGA/GNS lines, so a log recorded at
    10 Hz replays at 10 Hz (or 10k Hz with speed=k).
    """
    t0_wall: float | None = None
    t0_log: float | None = None
    with open(path, encoding="ascii", errors="replace") as fh:
        for raw in fh:
            line = raw.rstrip("\r\n")
            if speed:
                tod = _tod(line)
                if tod is not None:
                    if t0_log is None or tod < t0_log:
                        t0_log, t0_wall = tod, time.monotonic()
                    else:
                        assert t0_wall is not None
                        wait = t0_wall + (tod - t0_log) / speed - time.monotonic()
                        if wait > 0:
                            time.sleep(wait)
            yield line


def serial_lines(port: str, baudrate: int = 115200, timeout_s: float = 1.0) -> Iterator[str]:
    """Lines from a serial receiver (pyserial), reopening the port after errors."""
    import serial  # pyserial: imported here so other sources work without a port

    while True:
        try:
            with serial.Serial(port, baudrate=baudrate, timeout=timeout_s) as ser:
                while True:
                    raw = ser.readline()
                    if raw:
                        yield raw.decode("ascii", "replace").rstrip("\r\n")
                    else:
                        yield ""  # timeout: lets the runtime notice a silent receiver
        except serial.SerialException as exc:
            log.warning("serial %s: %s; retrying in 1 s", port, exc)
            time.sleep(1.0)


def tcp_lines(host: str, port: int, timeout_s: float = 2.0) -> Iterator[str]:
    """Lines from an NMEA TCP server (NTRIP caster relays, receivers' TCP ports)."""
    while True:
        try:
            with socket.create_connection((host, port), timeout=timeout_s) as sock:
                buf = b""
                while True:
                    try:
                        chunk = sock.recv(4096)
                    except TimeoutError:
                        yield ""
                        continue
                    if not chunk:
                        break
                    buf += chunk
                    *lines, buf = buf.split(b"\n")
                    for ln in lines:
                        yield ln.decode("ascii", "replace").rstrip("\r")
        except OSError as exc:
            log.warning("tcp %s:%s: %s; reconnecting in 1 s", host, port, exc)
            time.sleep(1.0)


def udp_lines(bind_host: str, port: int, timeout_s: float = 2.0) -> Iterator[str]:
    """Lines from UDP datagrams (one or more sentences per datagram)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((bind_host, port))
    sock.settimeout(timeout_s)
    try:
        while True:
            try:
                data, _ = sock.recvfrom(65535)
            except TimeoutError:
                yield ""
                continue
            for ln in data.split(b"\n"):
                if ln.strip():
                    yield ln.decode("ascii", "replace").rstrip("\r")
    finally:
        sock.close()


def open_source(spec: str, speed: float | None = None) -> Iterator[str]:
    """Source from a spec: ``file:PATH``, ``serial:/dev/ttyUSB0[@115200]``, ``tcp:host:port``,
    ``udp:port`` or ``udp:host:port``; a bare path is a file."""
    kind, _, rest = spec.partition(":")
    if kind == "serial":
        port, _, baud = rest.partition("@")
        return serial_lines(port, int(baud or 115200))
    if kind == "tcp":
        host, _, port = rest.rpartition(":")
        return tcp_lines(host or "127.0.0.1", int(port))
    if kind == "udp":
        host, _, port = rest.rpartition(":")
        return udp_lines(host or "0.0.0.0", int(port))
    if kind == "file":
        return file_lines(rest, speed)
    return file_lines(spec, speed)
