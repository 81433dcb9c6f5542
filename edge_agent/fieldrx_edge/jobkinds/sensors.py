"""Sensor lines of the sensor job kinds, and the guard that holds, then stops, on bad input.

Line formats (serial at the sensor's rate, or a file replayed):

* Canopy sensors, ACS-430 style: ``$NDVI,<t>,<n1>,...,<nk>*HH`` where ``HH`` is the NMEA
  checksum (XOR of the bytes between ``$`` and ``*``, two hex digits) and ``t`` the sensor
  time in s (may be empty). The bare CSV of ``fieldrx-edge ndvi`` (``t,n1..nk`` or
  ``n1..nk``) is accepted too. Every NDVI must lie in [-1, 1].
* Depth sensor (seed 002's tilt sensor through its ADC): ``$DEPTH,<t>,<mV>*HH`` or bare
  ``t,mV`` / ``mV``. The signal must lie in the calibration's valid range (eq. 13:
  2628-4356 mV by default).

``parse_*`` return the value or raise ``SensorError`` with a reason (counted by kind);
``SensorGuard`` turns that into the loop's safe output: the last good value for at most
``hold_s`` (alarm ``sensor_fault``), then none (alarm ``sensor_lost``: the caller stops
metering / holds the actuator still). Silence is the same as bad lines: the caller asks
``guard.value(now)`` on its own clock.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field


class SensorError(ValueError):
    """A sensor line was rejected; ``reason`` is one of format, checksum, range."""

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message)
        self.reason = reason


def nmea_checksum(body: str) -> str:
    c = 0
    for ch in body.encode("ascii", "replace"):
        c ^= ch
    return f"{c:02X}"


def _fields(line: str, tag: str) -> tuple[float | None, list[str]]:
    s = line.strip()
    if s.startswith("$"):
        body, star, cs = s[1:].partition("*")
        if not star or len(cs) < 2:
            raise SensorError("format", f"{tag} line without *checksum: {s[:60]!r}")
        if cs[:2].upper() != nmea_checksum(body):
            raise SensorError("checksum", f"{tag} checksum {cs[:2]} != {nmea_checksum(body)}")
        parts = body.split(",")
        if parts[0] != tag:
            raise SensorError("format", f"expected ${tag}, got ${parts[0]}")
        t = float(parts[1]) if len(parts) > 1 and parts[1] else None
        return t, parts[2:]
    return None, s.split(",")


def _floats(parts: list[str], tag: str) -> list[float]:
    try:
        vals = [float(p) for p in parts]
    except ValueError as exc:
        raise SensorError("format", f"{tag}: not a number ({exc})") from exc
    if not all(math.isfinite(v) for v in vals):
        raise SensorError("range", f"{tag}: non-finite value")
    return vals


def parse_ndvi(line: str, n_sensors: int) -> tuple[float | None, list[float]]:
    """(t, per-sensor NDVI) of one canopy-sensor line; ``SensorError`` when unusable."""
    t, parts = _fields(line, "NDVI")
    vals = _floats(parts, "NDVI")
    if t is None and len(vals) == n_sensors + 1:
        t, vals = vals[0], vals[1:]
    if len(vals) != n_sensors:
        raise SensorError("format", f"NDVI: {len(vals)} values, expected {n_sensors} sensors")
    bad = [v for v in vals if not -1.0 <= v <= 1.0]
    if bad:
        raise SensorError("range", f"NDVI {bad[0]!r} outside [-1, 1]")
    return t, vals


def parse_depth_mv(line: str, min_mv: float, max_mv: float) -> tuple[float | None, float]:
    """(t, signal mV) of one depth-sensor line; ``SensorError`` when unusable or out of range."""
    t, parts = _fields(line, "DEPTH")
    vals = _floats(parts, "DEPTH")
    if t is None and len(vals) == 2:
        t, vals = vals[0], vals[1:]
    if len(vals) != 1:
        raise SensorError("format", f"DEPTH: {len(vals)} values, expected 1 (mV)")
    mv = vals[0]
    if not min_mv <= mv <= max_mv:
        raise SensorError("range", f"depth signal {mv:g} mV outside {min_mv:g}..{max_mv:g} mV")
    return t, mv


def ndvi_line(t: float, values: list[float]) -> str:
    body = "NDVI," + f"{t:.2f}," + ",".join(f"{v:.4f}" for v in values)
    return f"${body}*{nmea_checksum(body)}"


def depth_line(t: float, mv: float) -> str:
    body = f"DEPTH,{t:.3f},{mv:.1f}"
    return f"${body}*{nmea_checksum(body)}"


@dataclass
class SensorGuard:
    """Last good value for at most ``hold_s``, then nothing (the caller stops and alarms)."""

    hold_s: float
    last_value: float | None = None
    last_good_t: float | None = None
    errors: Counter = field(default_factory=Counter)

    def good(self, t: float, value: float) -> None:
        self.last_value = value
        self.last_good_t = t

    def bad(self, reason: str) -> None:
        self.errors[reason] += 1

    def value(self, t: float) -> tuple[float | None, list[str]]:
        """(value to use, alarms) at time ``t``: fresh, held (sensor_fault), or lost."""
        if self.last_good_t is None:
            return None, ["sensor_lost"]
        age = t - self.last_good_t
        if age <= 1e-9:
            return self.last_value, []
        if age <= self.hold_s + 1e-9:
            return self.last_value, ["sensor_fault"]
        return None, ["sensor_lost"]
