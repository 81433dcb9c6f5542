"""Seed 000's sensor-based topdressing: canopy NDVI decides the rate on the go.

The kind's settings (the papers' values as defaults), its form, its controllers and the
agent's entry points; the loop itself is ``jobkinds/topdress.py``.
"""

from __future__ import annotations

import argparse
from typing import Any, ClassVar, Literal

from fieldrx_edge.jobkinds.registry import JobKind, Needs, SettingSpec, register
from fieldrx_edge.jobkinds.settings import SettingsError, number

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


@register
class NdviTopdress(JobKind):
    name: ClassVar[str] = "ndvi_topdress"
    label: ClassVar[str] = "Sensor-based topdressing, NDVI (seed 000)"
    noun: ClassVar[str] = "NDVI topdressing"
    source: ClassVar[str] = "seed 000"
    rates_from: ClassVar[Literal["cells", "sensors"]] = "sensors"
    progress: ClassVar[Literal["cells", "work"]] = "work"
    order: ClassVar[int] = 10
    cab_panel: ClassVar[str] = "ndvi"
    defaults: ClassVar[dict[str, Any]] = NDVI_DEFAULTS
    controllers: ClassVar[tuple[str, ...]] = ("isp", "incremental_pid", "ladrc")
    needs: ClassVar[Needs] = Needs(
        applies="fertiliser",
        sensors=("canopy_ndvi",),
        text="an implement that applies fertiliser and canopy NDVI sensors "
        "(capabilities.sensors: canopy_ndvi), seed 000",
    )
    specs: ClassVar[tuple[SettingSpec, ...]] = (
        SettingSpec("rate_curve.ndvi_lo", "Low NDVI", "NDVI", "seed 000", step=0.01),
        SettingSpec("rate_curve.rate_at_lo_kg_ha", "Rate at low NDVI", "kg/ha", "seed 000"),
        SettingSpec("rate_curve.ndvi_hi", "High NDVI", "NDVI", "seed 000", step=0.01),
        SettingSpec("rate_curve.rate_at_hi_kg_ha", "Rate at high NDVI", "kg/ha", "seed 000"),
        SettingSpec("sensors.count", "Canopy sensors", "sensors", "seed 000 (ACS-430)"),
        SettingSpec(
            "sensors.layout",
            "Sensor layout",
            "",
            "seed 000 Table 1",
            options=("distributed", "over_row"),
        ),
        SettingSpec("sensors.height_m", "Sensor height", "m", "seed 000", step=0.01),
        SettingSpec("window", "Sliding window", "samples", "seed 000"),
        SettingSpec(
            "controller.name",
            "Shaft controller",
            "",
            "seed 000 eq. 11-12",
            options=("isp", "incremental_pid", "ladrc"),
        ),
        SettingSpec("sensor_hold_s", "Hold last good reading", "s", step=0.1),
        SettingSpec(
            "restrict_to_boundary",
            "Only inside the field boundary",
            options=("true", "false"),
        ),
    )

    def controller_defaults(self, name: str) -> dict[str, Any]:
        if name == "ladrc":
            return {"params": dict(NDVI_LADRC_PARAMS), "period_s": 0.02}
        if name == "incremental_pid":
            return {"params": {**NDVI_DEFAULTS["controller"]["params"], "rule": "none"}}
        return {"params": {}}

    def run(self, a: argparse.Namespace, job: Any, store: Any) -> int | None:
        from fieldrx_edge.commands.kinds import run_kind, topdress_lines

        return run_kind(a, job, store, topdress_lines)

    def simulate(self, a: argparse.Namespace, job: Any) -> int | None:
        from fieldrx_edge.commands.kinds import simulate_kind
        from fieldrx_edge.jobkinds.topdress import simulate_topdress

        return simulate_kind(a, job, simulate_topdress)

    def check(self, s: dict[str, Any]) -> None:
        """The NDVI topdressing settings (seed 000), checked in place."""
        lo = number(s, "rate_curve.ndvi_lo", -1.0, 1.0, "NDVI")
        hi = number(s, "rate_curve.ndvi_hi", -1.0, 1.0, "NDVI")
        if hi <= lo:
            raise SettingsError("rate_curve.ndvi_hi", f"must be above ndvi_lo ({lo:g})")
        number(s, "rate_curve.rate_at_lo_kg_ha", 0.0, 2000.0, "kg/ha")
        number(s, "rate_curve.rate_at_hi_kg_ha", 0.0, 2000.0, "kg/ha")
        n = number(s, "sensors.count", 1, 16, "sensors")
        if n != int(n):
            raise SettingsError("sensors.count", "must be a whole number")
        s["sensors"]["count"] = int(n)
        if s["sensors"]["layout"] not in ("distributed", "over_row"):
            raise SettingsError(
                "sensors.layout", "must be distributed or over_row (seed 000 sec. 2.1)"
            )
        number(s, "sensors.height_m", 0.2, 3.0, "m")
        number(s, "sensors.sample_hz", 1.0, 20.0, "Hz")  # ACS-430: 1-20 Hz
        w = number(s, "window", 1, 200, "samples")
        if w != int(w):
            raise SettingsError("window", "must be a whole number of samples")
        s["window"] = int(w)
        number(s, "implement_width_m", 0.5, 60.0, "m")
        if not isinstance(s["restrict_to_boundary"], bool):
            raise SettingsError("restrict_to_boundary", "must be true or false")
        bands = s["speed_bands_kmh"]
        if (
            not isinstance(bands, list)
            or not 1 <= len(bands) <= 12
            or any(
                isinstance(b, bool) or not isinstance(b, int | float) or not 0 < b < 40
                for b in bands
            )
            or any(b >= c for b, c in zip(bands, bands[1:], strict=False))
        ):
            raise SettingsError(
                "speed_bands_kmh", "must be 1-12 increasing test speeds in km/h (0..40)"
            )
