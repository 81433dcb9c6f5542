"""What the cab screen shows, kept up to date from the session's own records.

``LiveState`` is a session observer: every record the loop queues passes through it
first, so the screen shows exactly what the agent decided and sends (the cell, the target
and applied rate, the alarms), never a second computation of its own. It also writes the
operator's side into those records before they are queued: the alarms it raises itself
(rate error, GNSS degraded, uplink backlog high), the acknowledgement of latched alarms,
and the operator's actions (``cab.operator``), so the server's job report sees them.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from fieldrx_edge.cab.geometry import JobGeometry
from fieldrx_edge.cab.operator import Operator
from fieldrx_edge.job_package import JobPackage

# what the screen latches and how it names it; record alarms map to these
ALARM_LABELS: dict[str, str] = {
    "rate_error": "Rate error",
    "shaft_above_range": "Shaft saturated (above meter range)",
    "shaft_below_range": "Shaft below meter range",
    "motor_saturated": "Motor at its limit",
    "sensor_fault": "Sensor reading bad",
    "sensor_lost": "Sensor silent: output stopped",
    "fix_lost": "GNSS lost",
    "gnss_degraded": "GNSS degraded",
    "outside_field": "Outside the field",
    "isobus_client_lost": "ISOBUS implement lost",
    "isobus_no_client": "No ISOBUS implement",
    "isobus_address_lost": "ISOBUS address lost",
    "isobus_address_conflict": "ISOBUS address conflict",
    "isobus_bus_off": "CAN bus off",
    "uplink_backlog_high": "Uplink backlog high",
    "speed_out_of_range": "Speed outside the planned band",
}


@dataclass
class CabLimits:
    """When the screen raises an alarm of its own."""

    rate_tolerance: float = 0.15  # |applied - target| / target beyond this ...
    rate_error_s: float = 1.0  # ... for this long: rate error
    max_hdop: float = 2.0  # above: GNSS degraded
    backlog_alarm: int = 3000  # queued records (5 min at 10 Hz): uplink backlog high


@dataclass
class Latched:
    name: str
    first_wall: float  # when the screen first saw it (wall clock, s)
    active: bool = True
    acked: bool = False
    count: int = 1


@dataclass
class Progress:
    """Running totals the screen shows (area, product, distance)."""

    applied_kg: float = 0.0
    distance_m: float = 0.0
    covered: set[int] = field(default_factory=set)
    order: list[int] = field(default_factory=list)  # covered cells in the order covered


class LiveState:
    """The session's live view; ``observe`` runs in the loop's thread, ``snapshot`` in the
    server's, under one lock (the loop holds it for microseconds per record)."""

    def __init__(
        self,
        job: JobPackage,
        operator: Operator,
        limits: CabLimits | None = None,
        backlog: Any = None,
        uplink: Any = None,
    ) -> None:
        self.job = job
        self.geo = JobGeometry(job)
        self.operator = operator
        self.limits = limits or CabLimits()
        self.backlog = backlog or (lambda: 0)
        self.uplink = uplink or (lambda: "offline")
        self.lock = threading.Lock()
        self.changed = threading.Condition(self.lock)
        self.rec: dict[str, Any] = {}
        self.rec_wall = 0.0
        self.n = 0
        self.latched: dict[str, Latched] = {}
        self.progress = Progress()
        self.tank_kg: float | None = None
        self._rate_bad_since: float | None = None
        self._last_t: float | None = None
        self._ack: list[str] = []
        self.state = "running"
        self.summary: dict[str, Any] | None = None  # set when the job ends
        self.depth_window: list[tuple[float, bool]] = []  # (distance m, qualified)

    # -- the loop's side -------------------------------------------------

    def observe(self, rec: dict[str, Any]) -> None:
        own = self._own_alarms(rec)
        with self.lock:
            alarms = [a for a in rec.get("alarms") or [] if a not in own] + own
            self.operator.tag(rec, alarms)
            if self._ack:
                alarms = sorted(set(alarms) | set(self._ack) | {"alarm_ack"})
                self._ack = []
            rec["alarms"] = alarms
            self._latch(alarms)
            self._advance(rec)
            self.rec = rec
            self.rec_wall = time.time()
            self.n += 1
            self.changed.notify_all()

    def _own_alarms(self, rec: dict[str, Any]) -> list[str]:
        lim = self.limits
        out: list[str] = []
        tr, ar = rec.get("target_rate_kg_ha"), rec.get("applied_rate_kg_ha")
        t = float(rec.get("t") or 0.0)
        bad = (
            rec.get("implement_down")
            and tr is not None
            and ar is not None
            and tr > 0
            and ar > 0  # stopped on purpose (pause, section off) is not a rate error
            and abs(ar - tr) > lim.rate_tolerance * tr
        )
        if bad:
            self._rate_bad_since = self._rate_bad_since if self._rate_bad_since else t
            if t - self._rate_bad_since >= lim.rate_error_s:
                out.append("rate_error")
        else:
            self._rate_bad_since = None
        hdop = rec.get("hdop")
        if hdop is not None and hdop > lim.max_hdop and rec.get("fix_quality", 0) > 0:
            out.append("gnss_degraded")
        if self.backlog() > lim.backlog_alarm:
            out.append("uplink_backlog_high")
        return out

    def _latch(self, alarms: list[str]) -> None:
        now = time.time()
        seen = {a for a in alarms if a in ALARM_LABELS}
        for name, la in self.latched.items():
            la.active = name in seen
        for a in seen:
            held = self.latched.get(a)
            if held is None or held.acked and not held.active:
                self.latched[a] = Latched(a, now)
            else:
                held.active = True
                la.count += 1

    def _advance(self, rec: dict[str, Any]) -> None:
        p = self.progress
        t = float(rec.get("t") or 0.0)
        dt = rec.get("fix_period_s") or (t - self._last_t if self._last_t else 0.0)
        dt = dt if 0.0 < dt <= 2.0 else 0.0
        self._last_t = t
        v = rec.get("speed_filtered_m_s") or 0.0
        p.distance_m += v * dt
        ar = rec.get("applied_rate_kg_ha")
        if ar:  # kg/ha over the strip driven: rate * width * v * dt / 10,000 m^2
            p.applied_kg += ar * self.job.implement_width_m * v * dt / 10_000.0
        cell = rec.get("cell_seq")
        if rec.get("implement_down") and cell is not None and (ar is None or ar > 0):
            if cell not in p.covered:
                p.covered.add(int(cell))
                p.order.append(int(cell))
        if rec.get("depth_mm") is not None:
            self._depth_window(rec, v * dt)

    def _depth_window(self, rec: dict[str, Any], step_m: float) -> None:
        """Seed 002's qualified depth (GB/T 20865 band around the target) over the job's
        trailing ``alert_window_m``, as ``jobkinds.figures.qualified_alert`` counts it."""
        from fieldrx_edge.jobkinds.figures import qualified_band_mm

        ks = self.job.kind_settings
        lo, hi = qualified_band_mm(float(ks.get("target_depth_mm", 30.0)))
        ok = lo <= float(rec["depth_mm"]) <= hi
        w = self.depth_window
        w.append((step_m, ok))
        total = sum(s for s, _ in w)
        while w and total - w[0][0] > float(ks.get("alert_window_m", 50.0)):
            total -= w.pop(0)[0]

    # -- the operator's side ---------------------------------------------

    def acknowledge(self) -> list[str]:
        """Acknowledge every latched alarm; the next record carries them and ``alarm_ack``."""
        with self.lock:
            names = [n for n, la in self.latched.items() if not la.acked]
            for n in names:
                self.latched[n].acked = True
            self.latched = {n: la for n, la in self.latched.items() if la.active or not la.acked}
            self._ack.extend(n for n in names if n not in self._ack)
            self.changed.notify_all()
            return names

    # -- the screen's side -----------------------------------------------

    def snapshot(self, since: int = 0) -> dict[str, Any]:
        """The screen's state; ``cells_from`` / ``new_cells``: covered cells from the
        client's cursor ``since`` on (each client keeps its own)."""
        with self.lock:
            rec = dict(self.rec)
            new = self.progress.order[since:]
            latched = [
                {"name": la.name, "label": ALARM_LABELS.get(la.name, la.name),
                 "active": la.active, "acked": la.acked, "first_wall": la.first_wall}
                for la in self.latched.values()
            ]  # fmt: skip
            applied_kg = self.progress.applied_kg
            covered = len(self.progress.covered)
            window = list(self.depth_window)
        out: dict[str, Any] = {
            "n": self.n,
            "rec_wall": self.rec_wall,
            "wall": time.time(),
            "state": self.state,
            "summary": self.summary,
            "rec": rec,
            "cells_from": since,
            "new_cells": new,
            "alarms": latched,
            "uplink": {"state": self.uplink(), "backlog": self.backlog()},
            "operator": self.operator.to_dict(),
        }
        out.update(self._derived(rec, applied_kg, covered, window))
        return out

    def _derived(
        self, rec: dict[str, Any], applied_kg: float, covered: int, window: list[Any]
    ) -> dict[str, Any]:
        job, geo = self.job, self.geo
        done = geo.area_of(self.covered_cells())
        out: dict[str, Any] = {
            "area": {"done_ha": done / 1e4, "left_ha": max(0.0, geo.total_area - done) / 1e4},
            "cells_covered": covered,
            "product": {"applied_kg": applied_kg, "tank_kg": self.tank_kg},
            "speed_band_m_s": [job.speed_min_m_s, job.speed_max_m_s],
            "meter_rpm": [geo.min_rpm, geo.max_rpm],
            "age_s": time.time() - self.rec_wall if self.rec_wall else None,
        }
        if self.tank_kg is not None:
            left = max(0.0, self.tank_kg - applied_kg)
            per_m = applied_kg / self.progress.distance_m if self.progress.distance_m > 0 else 0
            out["product"].update(left_kg=left, lasts_m=left / per_m if per_m > 0 else None)
        if rec.get("lon") is not None and rec.get("lat") is not None:
            x, y = geo.local(rec)
            out["pos"] = [x - geo.ox, y - geo.oy]
            out["guidance"] = geo.guidance(rec, x, y)
        if window:
            total = sum(s for s, _ in window)
            good = sum(s for s, ok in window if ok)
            out["depth"] = {
                "qualified_pct": 100.0 * good / total if total > 0 else None,
                "window_m": total,
                "target_mm": job.kind_settings.get("target_depth_mm"),
            }
        return out

    def covered_cells(self) -> set[int]:
        return set(self.progress.covered)


def finite(v: Any) -> bool:
    return isinstance(v, int | float) and math.isfinite(v)
