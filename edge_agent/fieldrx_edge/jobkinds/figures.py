"""The papers' Table 3 figures from telemetry-like records: one definition for simulator,
bench and server report.

Records are dicts (or rows) with ``t`` (s), ``speed`` (m/s, the filtered GNSS speed the
agent used), ``down`` (implement down), and per kind:

* seed 000: ``target_rpm`` (theoretical shaft speed from NDVI, rate and speed) and
  ``actual_rpm`` (monitored, encoder). Seed 000 Table 3 groups by the four test speeds
  (3.6 / 5.2 / 6.4 / 7.9 km/h measured) and gives |monitored - theoretical| / theoretical;
  its 3.35 % is the mean of the four band means. The paper analysed the constant-speed
  stretches, so a record counts only after ``settle_s`` of continuous implement-down
  driving without alarms (the spin-up at each swath start is a transient, not accuracy);
  a record is in the band of the nearest test speed.
* seed 002: ``depth_mm`` (measured depth). Table 3 groups by 1-3 / 3-5 / 5-7 km/h and gives
  mean, qualified share (GB/T 20865), standard deviation and CV; records with a sensor
  alarm carry a held value, not a measurement, and are left out.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

from fieldrx_edge.depth import depth_quality, qualified_band_mm

SETTLE_S = 2.0
EXCLUDING_ALARMS = frozenset({"sensor_fault", "sensor_lost", "outside_field", "fix_lost"})


def _settled(records: list[dict[str, Any]], settle_s: float) -> list[dict[str, Any]]:
    out = []
    since: float | None = None
    for r in sorted(records, key=lambda r: r["t"]):
        ok = r.get("down") and not (set(r.get("alarms") or ()) & EXCLUDING_ALARMS)
        if not ok:
            since = None
            continue
        if since is None:
            since = r["t"]
        if r["t"] - since >= settle_s:
            out.append(r)
    return out


def shaft_table(
    records: Iterable[dict[str, Any]], test_speeds_kmh: list[float], settle_s: float = SETTLE_S
) -> dict[str, Any]:
    """Seed 000 Table 3: per test speed, mean theoretical and monitored shaft speed (r/min)
    and mean relative error (%); ``mean_relative_error_pct`` is the mean over bands."""
    rows = [
        r
        for r in _settled(list(records), settle_s)
        if r.get("target_rpm") and r.get("actual_rpm") is not None and r.get("speed") is not None
    ]
    bands: list[dict[str, Any]] = []
    acc: list[list[tuple[float, float, float]]] = [[] for _ in test_speeds_kmh]
    for r in rows:
        v = r["speed"] * 3.6
        k = min(range(len(test_speeds_kmh)), key=lambda i: abs(test_speeds_kmh[i] - v))
        acc[k].append((r["target_rpm"], r["actual_rpm"], v))
    for sp, a in zip(test_speeds_kmh, acc, strict=True):
        if not a:
            bands.append({"speed_kmh": sp, "n": 0})
            continue
        n = len(a)
        bands.append(
            {
                "speed_kmh": sp,
                "n": n,
                "mean_speed_kmh": sum(x[2] for x in a) / n,
                "theoretical_rpm": sum(x[0] for x in a) / n,
                "monitored_rpm": sum(x[1] for x in a) / n,
                "relative_error_pct": 100.0 * sum(abs(x[1] - x[0]) / x[0] for x in a) / n,
            }
        )
    used = [b["relative_error_pct"] for b in bands if b["n"]]
    return {
        "bands": bands,
        "mean_relative_error_pct": sum(used) / len(used) if used else None,
        "settle_s": settle_s,
    }


def depth_table(
    records: Iterable[dict[str, Any]], bands_kmh: list[list[float]], target_mm: float
) -> dict[str, Any]:
    """Seed 002 Table 3 per speed band and overall: n, mean depth, qualified %, SD, CV."""
    rows = [
        r
        for r in records
        if r.get("down")
        and r.get("depth_mm") is not None
        and r.get("speed") is not None
        and not (set(r.get("alarms") or ()) & EXCLUDING_ALARMS)
    ]

    def q(vals: list[float]) -> dict[str, Any]:
        if len(vals) < 2:
            return {"n": len(vals)}
        m = depth_quality(vals, target_mm)
        return {
            "n": m.n,
            "mean_mm": m.mean_mm,
            "qualified_pct": m.pass_rate_pct,
            "sd_mm": m.std_mm,
            "cv_pct": m.cv_pct,
        }

    out = []
    for i, (lo, hi) in enumerate(bands_kmh):
        last = i == len(bands_kmh) - 1
        vals = [
            r["depth_mm"]
            for r in rows
            if lo <= r["speed"] * 3.6 < hi or (last and r["speed"] * 3.6 == hi)
        ]
        out.append({"speed_kmh": [lo, hi], **q(vals)})
    lo_mm, hi_mm = qualified_band_mm(target_mm)
    return {
        "target_mm": target_mm,
        "qualified_band_mm": [lo_mm, hi_mm],
        "bands": out,
        "all": q([r["depth_mm"] for r in rows]),
    }


def qualified_alert(
    records: Iterable[dict[str, Any]], target_mm: float, window_m: float, min_pct: float
) -> dict[str, Any]:
    """Qualified share over the trailing ``window_m`` metres of working (distance from speed
    x time); the alert fires where it first drops below ``min_pct`` after a full window."""
    lo, hi = qualified_band_mm(target_mm)
    rows = [
        r
        for r in sorted(records, key=lambda r: r["t"])
        if r.get("down") and r.get("depth_mm") is not None and r.get("speed") is not None
    ]
    dist: list[float] = []
    ok: list[int] = []
    s = 0.0
    prev_t: float | None = None
    worst = math.inf
    first: dict[str, Any] | None = None
    j = 0
    n_ok = 0
    for r in rows:
        if prev_t is not None:
            s += r["speed"] * max(0.0, min(r["t"] - prev_t, 1.0))
        prev_t = r["t"]
        dist.append(s)
        good = int(lo <= r["depth_mm"] <= hi)
        ok.append(good)
        n_ok += good
        while dist[j] < s - window_m:
            n_ok -= ok[j]
            j += 1
        if s >= window_m:
            share = 100.0 * n_ok / (len(ok) - j)
            worst = min(worst, share)
            if share < min_pct and first is None:
                first = {"seq": r.get("seq"), "t": r["t"], "qualified_pct": share, "at_m": s}
    return {
        "window_m": window_m,
        "min_qualified_pct": min_pct,
        "worst_qualified_pct": None if worst == math.inf else worst,
        "triggered": first is not None,
        "first": first,
    }
