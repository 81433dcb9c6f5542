"""Settings of the sensor job kinds: units in every name, the papers' values as defaults.

``validate_settings(kind, given)`` returns the complete settings (defaults filled in) or
raises ``SettingsError`` naming the field (dotted path) and the allowed range. The server
validates with it when a job is created and puts the result in the job package; the agent
reads the package's copy, so both sides run the same numbers.
"""

from __future__ import annotations

import copy
import math
from typing import Any

KINDS = ("prescription_map", "ndvi_topdress", "seeding_depth")


class SettingsError(ValueError):
    """A setting is missing, of the wrong type or out of range; ``where`` is its dotted path."""

    def __init__(self, where: str, message: str) -> None:
        super().__init__(f"settings.{where}: {message}")
        self.where = f"settings.{where}"


# Seed 000 (corn topdressing, 2020): NDVI 0.24 -> 375 kg/ha, 0.65 -> 180 kg/ha; four ACS-430
# sensors in the distributed layout 0.88 m high; sliding window 15; integral-separation
# incremental PID Kp 0.15, Ki 0.32, Kd 0.07, eps 0.7 (eq. 11-12) at a 0.1 s loop on encoder
# volts (plants/seeds.py); width 3.6 m; field test speeds 3.6 / 5.2 / 6.4 / 7.9 km/h (Table 3).
NDVI_DEFAULTS: dict[str, Any] = {
    "rate_curve": {
        "ndvi_lo": 0.24,
        "rate_at_lo_kg_ha": 375.0,
        "ndvi_hi": 0.65,
        "rate_at_hi_kg_ha": 180.0,
    },
    "sensors": {"count": 4, "layout": "distributed", "height_m": 0.88, "sample_hz": 10.0},
    "window": 15,
    "controller": {
        "name": "isp",
        "params": {"kp": 0.15, "ki": 0.32, "kd": 0.07, "eps": 0.7, "rule": "relative_change"},
        "period_s": 0.1,
    },
    "implement_width_m": 3.6,
    "restrict_to_boundary": True,
    "sensor_hold_s": 1.0,
    "speed_bands_kmh": [3.6, 5.2, 6.4, 7.9],
}
# Order-1 LADRC on the seed 000 shaft chain (10.3 r/min per V, T 0.16 s -> b0 = 64 r/min/(V s));
# the paper offers no ADRC for this motor: FieldRx's alternative, chosen in bench/seeds.py.
NDVI_LADRC_PARAMS: dict[str, float] = {"wc": 5.0, "wo": 20.0, "b0": 64.0, "order": 1}

# Seed 002 (wheat sowing depth, 2023): target 30 mm; GB/T 20865 band +-10 mm at >= 30 mm,
# +-5 mm below; eq. 13 y = -0.065 x + 270.35 over 2628-4356 mV; adaptive fuzzy PID with Table 2's
# universes and factors (fieldrx_edge.depth.TABLE2_FACTORS); cylinder 50 mm/s; 1 ms loop;
# field test bands 1-3 / 3-5 / 5-7 km/h (Table 3).
DEPTH_DEFAULTS: dict[str, Any] = {
    "target_depth_mm": 30.0,
    "sensor_calibration": {
        "slope_mm_per_mv": -0.065,
        "intercept_mm": 270.35,
        "signal_min_mv": 2628.0,
        "signal_max_mv": 4356.0,
    },
    "controller": {"name": "fuzzy_pid", "params": {}, "period_s": 0.001},
    "actuator_speed_mm_s": 50.0,
    "sensor_hold_s": 0.5,
    "speed_bands_kmh": [[1.0, 3.0], [3.0, 5.0], [5.0, 7.0]],
    "alert_window_m": 50.0,
    "alert_min_qualified_pct": 90.0,
}

DEFAULTS: dict[str, dict[str, Any]] = {
    "prescription_map": {},
    "ndvi_topdress": NDVI_DEFAULTS,
    "seeding_depth": DEPTH_DEFAULTS,
}
CONTROLLERS = {
    "ndvi_topdress": ("isp", "incremental_pid", "ladrc"),
    "seeding_depth": ("fuzzy_pid", "pid"),
}


def _merge(base: dict[str, Any], given: dict[str, Any], path: str) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for k, v in given.items():
        where = f"{path}{k}"
        if k not in base:
            raise SettingsError(where, f"unknown setting (known: {sorted(base)})")
        if isinstance(base[k], dict) and k != "params":
            if not isinstance(v, dict):
                raise SettingsError(where, "must be an object")
            out[k] = _merge(base[k], v, where + ".")
        else:
            out[k] = v
    return out


def _num(s: dict[str, Any], path: str, lo: float, hi: float, unit: str) -> float:
    obj: Any = s
    for part in path.split("."):
        obj = obj[part]
    if isinstance(obj, bool) or not isinstance(obj, int | float) or not math.isfinite(obj):
        raise SettingsError(path, f"must be a number ({unit}), got {obj!r}")
    if not lo <= obj <= hi:
        raise SettingsError(path, f"{obj:g} {unit} is outside {lo:g}..{hi:g} {unit}")
    return float(obj)


def validate_settings(kind: str, given: dict[str, Any] | None) -> dict[str, Any]:
    """Complete, checked settings of ``kind``; ``SettingsError`` names what is wrong."""
    if kind not in KINDS:
        raise SettingsError("kind", f"unknown job kind {kind!r} (known: {list(KINDS)})")
    given = given or {}
    if not isinstance(given, dict):
        raise SettingsError("", "must be an object")
    if kind == "prescription_map":
        if given:
            raise SettingsError(
                "", "a prescription-map job takes no settings (its rates are the cells')"
            )
        return {}
    s = _merge(DEFAULTS[kind], given, "")
    _check_controller(kind, given.get("controller", {}), s["controller"])
    _num(s, "controller.period_s", 1e-4, 1.0, "s")
    _num(s, "sensor_hold_s", 0.0, 10.0, "s")
    if kind == "ndvi_topdress":
        _check_ndvi(s)
    else:
        _check_depth(s)
    return s


def _check_controller(kind: str, given_ctl: dict[str, Any], ctl: dict[str, Any]) -> None:
    """Check the merged ``controller`` block in place; a controller other than the kind's
    default, named without its own params, gets that controller's defaults."""
    if ctl["name"] not in CONTROLLERS[kind]:
        raise SettingsError(
            "controller.name", f"{ctl['name']!r} is not one of {list(CONTROLLERS[kind])}"
        )
    if "params" in given_ctl and not isinstance(ctl["params"], dict):
        raise SettingsError("controller.params", "must be an object")
    if ctl["name"] != DEFAULTS[kind]["controller"]["name"] and "params" not in given_ctl:
        ctl["params"] = dict(NDVI_LADRC_PARAMS) if ctl["name"] == "ladrc" else {}
        if ctl["name"] == "incremental_pid":
            ctl["params"] = {**NDVI_DEFAULTS["controller"]["params"], "rule": "none"}
        if ctl["name"] == "ladrc" and "period_s" not in given_ctl:
            ctl["period_s"] = 0.02
    for k, v in ctl["params"].items():
        if k == "rule":
            if v not in ("relative_change", "error_band", "none"):
                raise SettingsError(
                    "controller.params.rule", "must be relative_change, error_band or none"
                )
        elif isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise SettingsError(f"controller.params.{k}", f"must be a number, got {v!r}")


def _check_ndvi(s: dict[str, Any]) -> None:
    """The NDVI topdressing settings (seed 000), checked in place."""
    lo = _num(s, "rate_curve.ndvi_lo", -1.0, 1.0, "NDVI")
    hi = _num(s, "rate_curve.ndvi_hi", -1.0, 1.0, "NDVI")
    if hi <= lo:
        raise SettingsError("rate_curve.ndvi_hi", f"must be above ndvi_lo ({lo:g})")
    _num(s, "rate_curve.rate_at_lo_kg_ha", 0.0, 2000.0, "kg/ha")
    _num(s, "rate_curve.rate_at_hi_kg_ha", 0.0, 2000.0, "kg/ha")
    n = _num(s, "sensors.count", 1, 16, "sensors")
    if n != int(n):
        raise SettingsError("sensors.count", "must be a whole number")
    s["sensors"]["count"] = int(n)
    if s["sensors"]["layout"] not in ("distributed", "over_row"):
        raise SettingsError("sensors.layout", "must be distributed or over_row (seed 000 sec. 2.1)")
    _num(s, "sensors.height_m", 0.2, 3.0, "m")
    _num(s, "sensors.sample_hz", 1.0, 20.0, "Hz")  # ACS-430: 1-20 Hz
    w = _num(s, "window", 1, 200, "samples")
    if w != int(w):
        raise SettingsError("window", "must be a whole number of samples")
    s["window"] = int(w)
    _num(s, "implement_width_m", 0.5, 60.0, "m")
    if not isinstance(s["restrict_to_boundary"], bool):
        raise SettingsError("restrict_to_boundary", "must be true or false")
    bands = s["speed_bands_kmh"]
    if (
        not isinstance(bands, list)
        or not 1 <= len(bands) <= 12
        or any(
            isinstance(b, bool) or not isinstance(b, int | float) or not 0 < b < 40 for b in bands
        )
        or any(b >= c for b, c in zip(bands, bands[1:], strict=False))
    ):
        raise SettingsError(
            "speed_bands_kmh", "must be 1-12 increasing test speeds in km/h (0..40)"
        )


def _check_depth(s: dict[str, Any]) -> None:
    """The sowing-depth settings (seed 002), checked in place."""
    _num(s, "target_depth_mm", 5.0, 120.0, "mm")
    _num(s, "sensor_calibration.slope_mm_per_mv", -10.0, 10.0, "mm/mV")
    if s["sensor_calibration"]["slope_mm_per_mv"] == 0:
        raise SettingsError("sensor_calibration.slope_mm_per_mv", "must not be 0")
    _num(s, "sensor_calibration.intercept_mm", -10000.0, 10000.0, "mm")
    a = _num(s, "sensor_calibration.signal_min_mv", 0.0, 20000.0, "mV")
    b = _num(s, "sensor_calibration.signal_max_mv", 0.0, 20000.0, "mV")
    if b <= a:
        raise SettingsError(
            "sensor_calibration.signal_max_mv", f"must be above signal_min_mv ({a:g})"
        )
    _num(s, "actuator_speed_mm_s", 1.0, 500.0, "mm/s")
    _num(s, "alert_window_m", 1.0, 10000.0, "m")
    _num(s, "alert_min_qualified_pct", 0.0, 100.0, "%")
    bands = s["speed_bands_kmh"]
    ok = isinstance(bands, list) and 1 <= len(bands) <= 12
    for i, band in enumerate(bands if ok else []):
        if (
            not isinstance(band, list)
            or len(band) != 2
            or any(isinstance(x, bool) or not isinstance(x, int | float) for x in band)
            or not 0 <= band[0] < band[1] <= 40
        ):
            raise SettingsError(f"speed_bands_kmh.{i}", "must be [low, high] km/h with low < high")
    if not ok:
        raise SettingsError("speed_bands_kmh", "must be 1-12 [low, high] bands in km/h")
