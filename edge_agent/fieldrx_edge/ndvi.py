"""Seed 000 NDVI mode: canopy sensors decide the rate on the go, no prescription needed.

Four Crop Circle sensors (two over rows, two off-row) are averaged per sample,
smoothed by a sliding-window mean of 15 samples (seed 000), mapped linearly
from NDVI 0.24 -> 375 kg/ha to 0.65 -> 180 kg/ha (less N where the crop is
greener), clamped to that range, and turned into a shaft speed with the
meter's table calibration (discharge per revolution depends on shaft speed).

Reading format (file or serial), one sample per line, comma separated:
``t,ndvi1,ndvi2,ndvi3,ndvi4`` or ``ndvi1,ndvi2,ndvi3,ndvi4``; lines starting
with ``#`` and lines that do not parse are counted and skipped.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Any

from fieldrx_edge.estimate import SlidingWindowMean
from fieldrx_edge.metering import TableCalibration, shaft_rpm_for_rate

# Seed 000: width 3.6 m, 3.5-8 km/h, 180-375 kg/ha at 7.2-36.9 r/min, so about
# 0.49-0.53 kg per revolution (Fig. 9 not digitised; this table is derived from
# the paper's end points and its stable 6-40 r/min range).
SEED000_TABLE = TableCalibration(
    rpm=(6.0, 15.0, 25.0, 40.0), g_per_rev=(525.0, 510.0, 498.0, 488.0), min_rpm=6.0, max_rpm=40.0
)
SEED000_WIDTH_M = 3.6


@dataclass(frozen=True)
class NdviRateMap:
    """Linear NDVI -> rate through two points, clamped to the rates between them."""

    ndvi_lo: float = 0.24
    rate_at_lo: float = 375.0
    ndvi_hi: float = 0.65
    rate_at_hi: float = 180.0

    def rate(self, ndvi: float) -> float:
        t = (ndvi - self.ndvi_lo) / (self.ndvi_hi - self.ndvi_lo)
        t = min(1.0, max(0.0, t))
        return self.rate_at_lo + t * (self.rate_at_hi - self.rate_at_lo)


@dataclass(slots=True)
class NdviSample:
    t: float | None
    values: tuple[float, ...]

    @property
    def mean(self) -> float:
        return sum(self.values) / len(self.values)


def parse_line(line: str, n_sensors: int = 4) -> NdviSample | None:
    line = line.strip()
    if not line or line.startswith("#"):
        return None
    try:
        parts = [float(p) for p in line.split(",")]
    except ValueError:
        return None
    if len(parts) == n_sensors + 1:
        t, vals = parts[0], parts[1:]
    elif len(parts) == n_sensors:
        t, vals = None, parts
    else:
        return None
    if not all(math.isfinite(v) and -1.0 <= v <= 1.0 for v in vals):
        return None
    return NdviSample(t, tuple(vals))


@dataclass
class NdviDecision:
    ndvi_raw: float
    ndvi: float
    rate_kg_ha: float
    target_rpm: float
    alarms: list[str]


class NdviMode:
    """Sample in, target shaft speed out (seed 000 processing chain)."""

    def __init__(
        self,
        width_m: float = SEED000_WIDTH_M,
        calibration: TableCalibration = SEED000_TABLE,
        rate_map: NdviRateMap | None = None,
        window: int = 15,
    ) -> None:
        self.width_m = width_m
        self.cal = calibration
        self.map = rate_map or NdviRateMap()
        self.filter = SlidingWindowMean(window)
        self.bad_lines = 0

    def on_sample(self, sample: NdviSample, speed_m_s: float) -> NdviDecision:
        raw = sample.mean
        ndvi = self.filter.update(raw)
        rate = self.map.rate(ndvi)
        rpm = shaft_rpm_for_rate(self.cal, rate, self.width_m, speed_m_s)
        alarms = []
        if rpm > 0 and rpm < self.cal.min_rpm:
            alarms.append("shaft_below_range")
            rpm = self.cal.min_rpm
        elif rpm > self.cal.max_rpm:
            alarms.append("shaft_above_range")
            rpm = self.cal.max_rpm
        return NdviDecision(raw, ndvi, rate, rpm, alarms)

    def samples(self, lines: Iterable[str]) -> Iterator[NdviSample]:
        for ln in lines:
            s = parse_line(ln)
            if s is None:
                if ln.strip() and not ln.startswith("#"):
                    self.bad_lines += 1
                continue
            yield s


class GnssSpeed:
    """Latest Kalman-filtered speed and position from a GNSS source, read in a thread."""

    def __init__(self, lines: Iterable[str]) -> None:
        from fieldrx_edge.estimate import KalmanSpeedFilter
        from fieldrx_edge.gnss.parser import NmeaParser

        self.parser = NmeaParser()
        self.kf = KalmanSpeedFilter()
        self.speed_m_s: float | None = None
        self.lon: float | None = None
        self.lat: float | None = None
        self.fix_quality = 0
        self._lines = lines
        self._th = threading.Thread(target=self._run, daemon=True)
        self._th.start()

    def _run(self) -> None:
        for ln in self._lines:
            for fx in self.parser.feed(ln):
                if fx.valid and fx.speed_m_s is not None:
                    self.speed_m_s = self.kf.update(fx.speed_m_s)
                    self.lon, self.lat, self.fix_quality = fx.lon, fx.lat, fx.fix_quality
                else:
                    self.fix_quality = 0


def run_ndvi(
    samples_lines: Iterable[str],
    mode: NdviMode,
    speed: GnssSpeed | float,
    motor: Any | None = None,
    queue: Any | None = None,
    machine_id: int = 1,
    on_decision: Any | None = None,
) -> int:
    """NDVI mode loop: each sensor sample sets the motor target and queues a record."""
    from fieldrx_edge.metering import rate_for_shaft_rpm
    from fieldrx_edge.protocol import TelemetryRecord

    n = 0
    for s in mode.samples(samples_lines):
        v = speed if isinstance(speed, float) else speed.speed_m_s
        if v is None:
            v = 0.0
        d = mode.on_sample(s, v)
        if motor is not None:
            motor.setpoint_rpm = d.target_rpm if v > 0 else 0.0
        if on_decision is not None:
            on_decision(d)
        if queue is not None:
            actual = motor.rpm if motor is not None else d.target_rpm
            lon = lat = None
            fq = 0
            if isinstance(speed, GnssSpeed):
                lon, lat, fq = speed.lon, speed.lat, speed.fix_quality
            rec = TelemetryRecord(
                machine_id=machine_id,
                seq=1,
                t=time.time(),
                lon=lon,
                lat=lat,
                fix_quality=fq,
                speed_filtered_m_s=v,
                target_rate_kg_ha=d.rate_kg_ha,
                applied_rate_kg_ha=rate_for_shaft_rpm(mode.cal, actual, mode.width_m, v),
                target_shaft_rpm=d.target_rpm,
                actual_shaft_rpm=actual,
                duty=motor.duty if motor is not None else None,
                ndvi=d.ndvi,
                implement_down=True,
                alarms=list(d.alarms),
            )
            queue.put(rec.to_dict())
        n += 1
    return n
