"""Settings of the job kinds: units in every name, the papers' values as defaults.

``validate_settings(kind, given)`` returns the complete settings (defaults filled in) or
raises ``SettingsError`` naming the field (dotted path) and the allowed range. The server
validates with it when a job is created and puts the result in the job package; the agent
reads the package's copy, so both sides run the same numbers. Each kind's defaults, specs
and own checks are in its module (``jobkinds/kinds/``, found through ``registry``); the
checks every kind shares (merging, numbers, the controller block) are here.
"""

from __future__ import annotations

import copy
import math
from typing import Any

from fieldrx_edge.jobkinds.registry import JobKind, UnknownKind, kind_of


class SettingsError(ValueError):
    """A setting is missing, of the wrong type or out of range; ``where`` is its dotted path."""

    def __init__(self, where: str, message: str) -> None:
        super().__init__(f"settings.{where}: {message}")
        self.where = f"settings.{where}"


def merge(base: dict[str, Any], given: dict[str, Any], path: str) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for k, v in given.items():
        where = f"{path}{k}"
        if k not in base:
            raise SettingsError(where, f"unknown setting (known: {sorted(base)})")
        if isinstance(base[k], dict) and k != "params":
            if not isinstance(v, dict):
                raise SettingsError(where, "must be an object")
            out[k] = merge(base[k], v, where + ".")
        else:
            out[k] = v
    return out


def number(s: dict[str, Any], path: str, lo: float, hi: float, unit: str) -> float:
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
    try:
        k = kind_of(kind)
    except UnknownKind as exc:
        raise SettingsError("kind", str(exc)) from None
    given = given or {}
    if not isinstance(given, dict):
        raise SettingsError("", "must be an object")
    if not k.defaults:
        if given:
            raise SettingsError("", f"a {k.noun} job takes no settings (its rates are the cells')")
        return {}
    s = merge(k.defaults, given, "")
    if "controller" in s:
        _check_controller(k, given.get("controller", {}), s["controller"])
        number(s, "controller.period_s", 1e-4, 1.0, "s")
    if "sensor_hold_s" in s:
        number(s, "sensor_hold_s", 0.0, 10.0, "s")
    k.check(s)
    return s


def _check_controller(k: JobKind, given_ctl: dict[str, Any], ctl: dict[str, Any]) -> None:
    """Check the merged ``controller`` block in place; a controller other than the kind's
    default, named without its own params, gets that controller's defaults."""
    if ctl["name"] not in k.controllers:
        raise SettingsError(
            "controller.name", f"{ctl['name']!r} is not one of {list(k.controllers)}"
        )
    if "params" in given_ctl and not isinstance(ctl["params"], dict):
        raise SettingsError("controller.params", "must be an object")
    if ctl["name"] != k.defaults["controller"]["name"] and "params" not in given_ctl:
        extra = k.controller_defaults(ctl["name"])
        ctl["params"] = extra["params"]
        if "period_s" in extra and "period_s" not in given_ctl:
            ctl["period_s"] = extra["period_s"]
    for key, v in ctl["params"].items():
        if key == "rule":
            if v not in ("relative_change", "error_band", "none"):
                raise SettingsError(
                    "controller.params.rule", "must be relative_change, error_band or none"
                )
        elif isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise SettingsError(f"controller.params.{key}", f"must be a number, got {v!r}")
