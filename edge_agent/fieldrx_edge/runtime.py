"""The agent's loops wired together.

At the GNSS rate (``Pipeline.on_fix``): fix -> UTM -> Kalman speed (seed 001
eq. 14-15) -> lag look-ahead (eq. 16: the outlet point shifted forward by
v * T_lag, so the rate changes where the fertilizer lands) -> boundary check
-> cell lookup (path order, finished cells dropped) -> target rate -> target
shaft speed (``metering``, eq. 1-3). The motor loop (``motor.MotorLoop``)
runs at a fixed rate on its own. Every fix becomes a telemetry record that
goes into the local queue before anything else sees it.

Metering stops when the implement is raised, outside the field, in a hole,
in an already-applied cell (overlap control), and after ``fix_loss_hold_s``
without a usable fix (the last rate is held until then).

Cells are the package's real shapes where it gives them (headland rings, field
edge, holes), else the 4-corner rectangles. While the machine turns inside a
run (a headland ring's corner) the straight look-ahead leaves the path: the
cell being applied is then neither finished early nor replaced by another
swath's cell, and metering stops early before already-applied cells as it does
before the field edge.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

from fieldrx_edge.estimate import KalmanSpeedFilter, look_ahead
from fieldrx_edge.gnss.parser import Fix, NmeaParser
from fieldrx_edge.gnss.utm import UtmProjection
from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.locate import CellLocator, FieldBoundary, Where
from fieldrx_edge.metering import (
    calibration_from_dict,
    rate_for_shaft_rpm,
    shaft_rpm_for_rate,
)
from fieldrx_edge.protocol import TelemetryRecord

log = logging.getLogger(__name__)


SATURATED_DUTY_PCT = 99.5  # controller output at its 100 % limit
TURN_COS = math.cos(math.radians(25.0))  # heading this far off the run's next cell: a turn
MAX_PERIOD_S = 2.0  # a longer interval between fixes is an outage, not a fix period


@dataclass
class RuntimeConfig:
    lag_compensation: bool = True
    response_s: float = 0.05  # motor loop's effective delay, added to the look-ahead
    gnss_period_s: float = 0.1  # half a fix period is added: the target holds until the next fix
    fix_timeout_s: float = 1.0  # no fix for this long counts as a loss of fix
    min_fix_quality: int = 1
    max_hdop: float | None = 5.0
    min_course_speed_m_s: float = 0.3  # below this the GNSS course is noise: keep the last heading
    stop_extra_s: float = 0.0  # extra look-ahead for stops at the field edge (coast-down)
    start_extra_s: float = 0.0  # extra look-ahead for starts from rest (spin-up)
    border_tolerance_m: float = 0.3  # jitter back over a border within this stays in the cell


@dataclass(slots=True)
class Decision:
    t: float
    metering: bool = False
    target_rate_kg_ha: float = 0.0
    target_rpm: float = 0.0
    cell: int = -1
    cell_seq: int | None = None
    x: float | None = None
    y: float | None = None
    lx: float | None = None  # look-ahead (landing) point
    ly: float | None = None
    speed_raw_m_s: float | None = None
    speed_m_s: float | None = None
    heading_deg: float | None = None
    reason: str = ""
    alarms: list[str] = field(default_factory=list)


@dataclass(frozen=True, slots=True)
class Measured:
    """What goes into a telemetry record beside the pipeline's decision: the motor's
    reading, the implement state and the fix time the record stands for."""

    actual_rpm: float
    duty: float
    implement_down: bool
    t: float  # receiver time of the fix (TelemetryRecord.t), not the time of writing
    backlog: int = 0
    ndvi: float | None = None
    fix_period_s: float | None = None  # the fix interval the record stands for


class Pipeline:
    """Per-fix decisions for one job; pure computation, no I/O (the simulator reuses it)."""

    def __init__(
        self,
        job: JobPackage,
        cfg: RuntimeConfig | None = None,
        finished: Iterable[int] = (),
        on_cell_finished: Callable[[int], None] | None = None,
    ) -> None:
        self.job = job
        self.cfg = cfg or RuntimeConfig()
        self.proj = UtmProjection(job.utm_epsg)
        self.locator = CellLocator(job.corners_utm, shapes=job.cell_shapes())
        self.boundary = FieldBoundary(job.boundary_utm)
        for i in finished:
            self.locator.finished[i] = True
        self.cal = calibration_from_dict(job.calibration)
        self.kf = KalmanSpeedFilter()
        self.rates = list(job.rate_kg_ha)
        # kg/ha in one of the job's rate unit, for the records; a lot the package does not
        # state (an l/ha job without a density, metered by volume only) leaves them as is
        u = job.unit()
        self.kg_per_unit = job.kg_per_unit() if u.known(job.lot()) else 1.0
        self.seqs = list(job.seq)
        self.swaths = list(job.swath)
        cxy = [job.corners_utm[8 * i : 8 * i + 8] for i in range(job.n_cells)]
        self._cx = [sum(c[0::2]) / 4 for c in cxy]
        self._cy = [sum(c[1::2]) / 4 for c in cxy]
        self.on_cell_finished = on_cell_finished
        self.heading_rad = 0.0
        self.last_good_t: float | None = None
        self.last: Decision | None = None
        self._applying = -1  # cell being applied (landing point inside, metering on)
        self._reach_m = 0.5  # look-ahead distance of the last fix (+0.5 m)

    # -- helpers ---------------------------------------------------------

    def look_ahead_time_s(self) -> float:
        c = self.cfg
        if not c.lag_compensation:
            return 0.0
        return self.job.lag_s + c.response_s + 0.5 * c.gnss_period_s

    def _finish_current(self) -> None:
        if self._applying >= 0:
            self.locator.finished[self._applying] = True
            if self.on_cell_finished is not None:
                self.on_cell_finished(self._applying)
            self._applying = -1

    def _stop(self, d: Decision, reason: str, finish: bool = True) -> Decision:
        """Metering off. ``finish``: the landing point has left the cell being applied."""
        d.metering = False
        d.target_rate_kg_ha = 0.0
        d.target_rpm = 0.0
        d.reason = reason
        if finish:
            self._finish_current()
        self.last = d
        return d

    # -- entry points ----------------------------------------------------

    def on_fix(self, fix: Fix, now: float, implement_down: bool = True) -> Decision:
        cfg = self.cfg
        usable = fix.valid and fix.fix_quality >= cfg.min_fix_quality
        if usable and cfg.max_hdop is not None and fix.hdop is not None:
            usable = fix.hdop <= cfg.max_hdop
        if not usable:
            return self.on_no_fix(now)
        if fix.x is None:
            assert fix.lon is not None and fix.lat is not None
            fix.x, fix.y = self.proj.forward(fix.lon, fix.lat)
        assert fix.y is not None  # set together with x
        return self.on_position(now, fix.x, fix.y, fix.speed_m_s, fix.course_deg, implement_down)

    def on_position(
        self,
        now: float,
        x: float,
        y: float,
        speed_raw: float | None,
        course_deg: float | None,
        implement_down: bool = True,
    ) -> Decision:
        """The pipeline for one usable fix already in UTM."""
        job, cfg = self.job, self.cfg
        self.last_good_t = now
        if speed_raw is None:
            speed_raw = self.last.speed_m_s if self.last and self.last.speed_m_s else 0.0
        v = self.kf.update(speed_raw)
        if v < 0:
            v = 0.0
        if course_deg is not None and speed_raw >= cfg.min_course_speed_m_s:
            self.heading_rad = math.radians(course_deg)  # clockwise from grid north
        # landing point: outlet (antenna + offsets) + v * T ahead (seed 001 eq. 16)
        lx, ly = look_ahead(
            x,
            y,
            self.heading_rad,
            v,
            self.look_ahead_time_s(),
            job.antenna_forward_m,
            job.antenna_lateral_m,
        )
        d = Decision(
            t=now,
            x=x,
            y=y,
            lx=lx,
            ly=ly,
            speed_raw_m_s=speed_raw,
            speed_m_s=v,
            heading_deg=math.degrees(self.heading_rad) % 360.0,
        )
        self._reach_m = v * self.look_ahead_time_s() + 0.5
        # with the implement raised (headland turns, transport) nothing is applied: the
        # speed range and the field edge do not matter, and flagging them painted the
        # fleet marker red at every turn
        if implement_down and not (job.speed_min_m_s <= v <= job.speed_max_m_s):
            d.alarms.append("speed_out_of_range")
        where = self.boundary.where(lx, ly)
        if where != Where.INSIDE:
            early = self._early_start(d, x, y, v, implement_down)
            if early is not None:
                return early
            if implement_down:
                d.alarms.append("outside_field")
            # a headland ring's corner: the straight look-ahead leaves the field for a
            # moment while the path stays in the cell being applied; do not finish it
            return self._stop(
                d,
                "outside_field" if where == Where.OUTSIDE else "hole",
                finish=not self._turning_in_run(self._applying, lx, ly),
            )
        idx = self._cell_at(lx, ly)
        d.cell = idx
        if idx < 0:
            early = self._early_start(d, x, y, v, implement_down)
            if early is not None:
                return early
            return self._stop(d, "no_cell", finish=not self._turning_in_run(self._applying, lx, ly))
        idx = self._kept_across_border(idx, lx, ly)
        d.cell = idx
        d.cell_seq = self.seqs[idx]
        if idx != self._applying:
            self._finish_current()
        stop_reason = self._stop_ahead(idx, x, y, v, lx, ly)
        if stop_reason:
            return self._stop(d, stop_reason, finish=False)
        if not implement_down:
            return self._stop(d, "implement_raised", finish=False)  # lowered again: resume
        if job.overlap_control and self.locator.finished[idx]:
            return self._stop(d, "already_applied")
        rate = self.rates[idx]
        if rate <= 0.0:
            return self._stop(d, "zero_rate")
        self._meter(d, rate, v, "metering")
        self._applying = idx
        return d

    def _cell_at(self, lx: float, ly: float) -> int:
        """The cell the look-ahead point (lx, ly) lands in, -1 for none."""
        idx = self.locator.locate(lx, ly)
        if (
            idx >= 0
            and self._applying >= 0
            and self.swaths[idx] != self.swaths[self._applying]
            and self._turning_in_run(self._applying, lx, ly)
        ):
            # ... or cuts across another swath's cells inside the corner: the fertilizer
            # lands on the ring's path, so keep the cell being applied (never start and
            # finish an inner cell before it is driven)
            idx = self._applying
        return idx

    def _kept_across_border(self, idx: int, lx: float, ly: float) -> int:
        """Cell ``idx`` (>= 0), or the cell being applied when noise crossed back into ``idx``."""
        if (
            idx != self._applying
            and self._applying >= 0
            and self.locator.finished[idx]
            and self.locator.distance_to_cell(self._applying, lx, ly) <= self.cfg.border_tolerance_m
        ):
            # GNSS noise pushed the point back over the border into the cell just
            # finished: keep applying the current cell rather than finishing it early
            idx = self._applying
        return idx

    def _stop_ahead(self, idx: int, x: float, y: float, v: float, lx: float, ly: float) -> str:
        """Why metering stops early before the edge or applied ground ahead ("" if it does not)."""
        cfg, job = self.cfg, self.job
        if not (cfg.lag_compensation and cfg.stop_extra_s > 0):
            return ""
        # the shaft coasts down slower than it follows a small step: stop a little
        # earlier before the field edge or a hole so the tail does not land outside
        sx, sy = look_ahead(
            x,
            y,
            self.heading_rad,
            v,
            self.look_ahead_time_s() + cfg.stop_extra_s,
            job.antenna_forward_m,
            job.antenna_lateral_m,
        )
        if self.boundary.where(sx, sy) != Where.INSIDE and not self._turning_in_run(idx, lx, ly):
            return "edge_ahead"
        if job.overlap_control and self._applied_ahead(idx, sx, sy):
            # the same before a headland ring already applied: the tail would land twice
            return "applied_ahead"
        return ""

    def _run_continues(self, idx: int) -> bool:
        """The path goes on in the same swath after cell ``idx`` (a headland ring turning
        a corner): the straight look-ahead leaving the field there is not an edge."""
        nxt = idx + 1
        return (
            idx >= 0
            and nxt < len(self.swaths)
            and self.swaths[nxt] == self.swaths[idx]
            and not self.locator.finished[nxt]
        )

    def _applied_ahead(self, idx: int, x: float, y: float) -> bool:
        """Is (x, y) in another cell already applied (the locator's path pointer is kept)?"""
        loc = self.locator
        cur = loc.current
        k = loc.locate(x, y)
        loc.current = cur
        return k >= 0 and k != idx and bool(loc.finished[k]) and not self._turning_in_run(idx, x, y)

    def _turning_in_run(self, idx: int, lx: float, ly: float) -> bool:
        """The machine turns inside a run (a headland ring's corner): the run goes on
        after cell ``idx`` but not where the machine heads (> 25 degrees off), so the
        straight look-ahead misses the path the fertilizer will land on. Only while the
        look-ahead point (lx, ly) is within the look-ahead distance of cell ``idx``:
        a cell left behind (implement raised, a headland turn) is no longer turned from."""
        if not self._run_continues(idx):
            return False
        dx = self._cx[idx + 1] - self._cx[idx]
        dy = self._cy[idx + 1] - self._cy[idx]
        norm = math.hypot(dx, dy)
        if norm == 0.0:
            return False
        cos = (dx * math.sin(self.heading_rad) + dy * math.cos(self.heading_rad)) / norm
        if cos >= TURN_COS:
            return False
        return self.locator.distance_to_cell(idx, lx, ly) <= self._reach_m

    def _meter(self, d: Decision, rate: float, v: float, reason: str) -> None:
        rpm = shaft_rpm_for_rate(self.cal, rate, self.job.implement_width_m, v)
        if rpm < self.cal.min_rpm:
            d.alarms.append("shaft_below_range")
            rpm = self.cal.min_rpm
        elif rpm > self.cal.max_rpm:
            d.alarms.append("shaft_above_range")
            rpm = self.cal.max_rpm
        d.metering = True
        d.target_rate_kg_ha = rate
        d.target_rpm = rpm
        d.reason = reason
        self.last = d

    def _early_start(
        self, d: Decision, x: float, y: float, v: float, implement_down: bool
    ) -> Decision | None:
        """Start the shaft ``start_extra_s`` early when the landing point is about to
        enter an unapplied cell: spinning up from rest is slower than a small step."""
        cfg, job = self.cfg, self.job
        if not (cfg.lag_compensation and cfg.start_extra_s > 0 and implement_down):
            return None
        if self._applying >= 0:
            return None
        sx, sy = look_ahead(
            x,
            y,
            self.heading_rad,
            v,
            self.look_ahead_time_s() + cfg.start_extra_s,
            job.antenna_forward_m,
            job.antenna_lateral_m,
        )
        if self.boundary.where(sx, sy) != Where.INSIDE:
            return None
        k = self.locator.locate(sx, sy)
        if k < 0 or (job.overlap_control and self.locator.finished[k]) or self.rates[k] <= 0:
            return None
        d.cell, d.cell_seq = k, self.seqs[k]
        self._meter(d, self.rates[k], v, "start_ahead")
        return d

    def on_no_fix(self, now: float) -> Decision:
        """Fix-loss policy: hold the last rate for ``fix_loss_hold_s``, then stop."""
        last = self.last
        d = Decision(t=now, alarms=["fix_lost"])
        if (
            last is not None
            and last.metering
            and self.last_good_t is not None
            and now - self.last_good_t <= self.job.fix_loss_hold_s
        ):
            d.metering = True
            d.target_rate_kg_ha = last.target_rate_kg_ha
            d.target_rpm = last.target_rpm
            d.cell, d.cell_seq = last.cell, last.cell_seq
            d.speed_m_s = last.speed_m_s
            d.heading_deg = last.heading_deg
            d.reason = "fix_lost_hold"
            return d  # self.last stays the last good decision
        d.reason = "fix_lost"  # the cell is not finished: resume in it when the fix returns
        if last is not None:
            last.metering = False
        return d

    def applied_rate(self, d: Decision, actual_rpm: float) -> float:
        if not d.metering or not d.speed_m_s:
            return 0.0
        return rate_for_shaft_rpm(self.cal, actual_rpm, self.job.implement_width_m, d.speed_m_s)


def make_record(pipe: Pipeline, d: Decision, fix: Fix | None, m: Measured) -> dict[str, Any]:
    """Telemetry record body (seq and machine_id are set by the queue)."""
    alarms = list(d.alarms)
    if d.metering and m.duty >= SATURATED_DUTY_PCT:
        alarms.append("motor_saturated")
    lon = lat = None
    if fix is not None and fix.lon is not None and fix.lat is not None:
        lon, lat = fix.lon, fix.lat
    elif d.x is not None and d.y is not None:
        lon, lat = pipe.proj.inverse(d.x, d.y)
    # records are kg/ha (the server's as-applied maps): a job in another unit (l/ha) back
    # to mass through the product lot its package carries (a liquid's density)
    kg = pipe.kg_per_unit
    rec = TelemetryRecord(
        machine_id=pipe.job.machine_id,
        seq=1,
        t=m.t,
        lon=lon,
        lat=lat,
        fix_quality=fix.fix_quality if fix is not None else (1 if d.x is not None else 0),
        hdop=fix.hdop if fix is not None else None,
        speed_raw_m_s=d.speed_raw_m_s,
        speed_filtered_m_s=d.speed_m_s,
        heading_deg=d.heading_deg,
        job_id=pipe.job.job_id,
        cell_seq=d.cell_seq,
        target_rate_kg_ha=d.target_rate_kg_ha * kg,
        applied_rate_kg_ha=pipe.applied_rate(d, m.actual_rpm) * kg,
        target_shaft_rpm=d.target_rpm,
        actual_shaft_rpm=m.actual_rpm,
        duty=m.duty,
        ndvi=m.ndvi,
        implement_down=m.implement_down,
        alarms=alarms,
        queue_backlog=m.backlog,
        fix_period_s=m.fix_period_s,
    )
    return rec.to_dict()


class Agent:
    """A job running live: NMEA lines in, motor commands and queued telemetry out."""

    def __init__(
        self,
        job: JobPackage,
        queue: Any,
        motor: Any,
        cfg: RuntimeConfig | None = None,
        finished: Iterable[int] = (),
        on_progress: Callable[[list[int]], None] | None = None,
        implement_down: Callable[[], bool] | None = None,
    ) -> None:
        self.job = job
        self.queue = queue
        self.motor = motor
        self._finished: list[int] = sorted(set(finished))
        self.on_progress = on_progress
        self.pipe = Pipeline(job, cfg, self._finished, self._cell_done)
        self.parser = NmeaParser(max_hdop=None)
        self.implement_down = implement_down or (lambda: True)
        self.records = 0
        self._backlog = 0
        self.lines = 0
        self._last_fix_wall = time.monotonic()
        self._last_fix_t: float | None = None

    def _cell_done(self, idx: int) -> None:
        self._finished.append(idx)
        if self.on_progress is not None:
            self.on_progress(self._finished)

    def handle_line(self, line: str) -> int:
        """Parse one line; run the pipeline for each completed fix. Returns records queued."""
        self.lines += 1
        n = 0
        now_wall = time.monotonic()
        fixes = self.parser.feed(line) if line else []
        for fix in fixes:
            self._last_fix_wall = now_wall
            # record time = the fix's own time (receiver clock); the period it stands for
            # is the receiver's fix interval, measured between consecutive fixes
            t = fix.t if fix.t is not None else time.time()
            prev, self._last_fix_t = self._last_fix_t, t
            period = t - prev if prev is not None and 0.0 < t - prev <= MAX_PERIOD_S else None
            down = self.implement_down()
            d = self.pipe.on_fix(fix, now_wall, down)
            self._emit(d, fix, down, t, period)
            n += 1
        if not fixes and now_wall - self._last_fix_wall > self.pipe.cfg.fix_timeout_s:
            self._last_fix_wall = now_wall  # one no-fix record per timeout period
            d = self.pipe.on_no_fix(now_wall)
            self._emit(d, None, self.implement_down(), time.time())
            n += 1
        return n

    def _emit(
        self, d: Decision, fix: Fix | None, down: bool, t: float, period: float | None = None
    ) -> None:
        self.motor.setpoint_rpm = d.target_rpm if d.metering else 0.0
        if hasattr(self.motor, "on_decision"):  # an ISOBUS implement takes rate + sections
            self.motor.on_decision(d)
        if self.records % 20 == 0:
            self._backlog = self.queue.backlog()  # one query per 20 records is plenty
        rec = make_record(
            self.pipe,
            d,
            fix,
            Measured(self.motor.rpm, self.motor.duty, down, t, self._backlog, fix_period_s=period),
        )
        self.queue.put(rec)
        self.records += 1
        self._backlog += 1

    def run(self, lines: Iterable[str], stop: threading.Event | None = None) -> None:
        stop = stop or threading.Event()
        motor_stop = threading.Event()
        th = threading.Thread(target=self.motor.run, args=(motor_stop,), daemon=True)
        th.start()
        try:
            for line in lines:
                if stop.is_set():
                    break
                self.handle_line(line)
        finally:
            motor_stop.set()
            th.join(timeout=2.0)
