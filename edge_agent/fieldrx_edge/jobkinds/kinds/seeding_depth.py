"""Seed 002's depth-controlled seeding: the sowing depth held by a closed loop.

The kind's settings (the paper's values as defaults), its form, its controllers and the
agent's entry points; the loop itself is ``jobkinds/seeding.py``.
"""

from __future__ import annotations

import argparse
from typing import Any, ClassVar, Literal

from fieldrx_edge.jobkinds.registry import JobKind, Needs, SettingSpec, register
from fieldrx_edge.jobkinds.settings import SettingsError, number

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


@register
class SeedingDepth(JobKind):
    name: ClassVar[str] = "seeding_depth"
    label: ClassVar[str] = "Seeding with depth control (seed 002)"
    noun: ClassVar[str] = "depth-controlled seeding"
    source: ClassVar[str] = "seed 002"
    rates_from: ClassVar[Literal["cells", "sensors"]] = "sensors"
    progress: ClassVar[Literal["cells", "work"]] = "work"
    order: ClassVar[int] = 20
    defaults: ClassVar[dict[str, Any]] = DEPTH_DEFAULTS
    controllers: ClassVar[tuple[str, ...]] = ("fuzzy_pid", "pid")
    needs: ClassVar[Needs] = Needs(
        applies="seed",
        sensors=("depth",),
        depth_actuator=True,
        text="a seeder with a depth actuator (capabilities.depth_actuator) and a "
        "depth sensor (capabilities.sensors: depth), seed 002",
    )
    shows_rate: ClassVar[bool] = False
    cab_panel: ClassVar[str] = "depth"
    specs: ClassVar[tuple[SettingSpec, ...]] = (
        SettingSpec("target_depth_mm", "Target depth", "mm", "seed 002"),
        SettingSpec(
            "sensor_calibration.slope_mm_per_mv",
            "Sensor slope",
            "mm/mV",
            "seed 002 eq. 13",
            step=0.001,
        ),
        SettingSpec(
            "sensor_calibration.intercept_mm", "Sensor intercept", "mm", "seed 002 eq. 13", 0.01
        ),
        SettingSpec("sensor_calibration.signal_min_mv", "Valid signal from", "mV", "seed 002"),
        SettingSpec("sensor_calibration.signal_max_mv", "Valid signal to", "mV", "seed 002"),
        SettingSpec(
            "controller.name",
            "Depth controller",
            "",
            "seed 002 sec. 2.3",
            options=("fuzzy_pid", "pid"),
        ),
        SettingSpec("actuator_speed_mm_s", "Cylinder speed", "mm/s", "seed 002 sec. 4.1"),
        SettingSpec("alert_window_m", "Alert window", "m"),
        SettingSpec("alert_min_qualified_pct", "Alert below qualified", "%"),
        SettingSpec("sensor_hold_s", "Hold last good reading", "s", step=0.1),
    )

    def run(self, a: argparse.Namespace, job: Any, store: Any) -> int | None:
        from fieldrx_edge.commands.kinds import depth_lines, run_kind

        return run_kind(a, job, store, depth_lines)

    def simulate(self, a: argparse.Namespace, job: Any) -> int | None:
        from fieldrx_edge.commands.kinds import simulate_kind
        from fieldrx_edge.jobkinds.seeding import simulate_seeding

        return simulate_kind(a, job, simulate_seeding)

    def check(self, s: dict[str, Any]) -> None:
        """The sowing-depth settings (seed 002), checked in place."""
        number(s, "target_depth_mm", 5.0, 120.0, "mm")
        number(s, "sensor_calibration.slope_mm_per_mv", -10.0, 10.0, "mm/mV")
        if s["sensor_calibration"]["slope_mm_per_mv"] == 0:
            raise SettingsError("sensor_calibration.slope_mm_per_mv", "must not be 0")
        number(s, "sensor_calibration.intercept_mm", -10000.0, 10000.0, "mm")
        a = number(s, "sensor_calibration.signal_min_mv", 0.0, 20000.0, "mV")
        b = number(s, "sensor_calibration.signal_max_mv", 0.0, 20000.0, "mV")
        if b <= a:
            raise SettingsError(
                "sensor_calibration.signal_max_mv", f"must be above signal_min_mv ({a:g})"
            )
        number(s, "actuator_speed_mm_s", 1.0, 500.0, "mm/s")
        number(s, "alert_window_m", 1.0, 10000.0, "m")
        number(s, "alert_min_qualified_pct", 0.0, 100.0, "%")
        bands = s["speed_bands_kmh"]
        ok = isinstance(bands, list) and 1 <= len(bands) <= 12
        for i, band in enumerate(bands if ok else []):
            if (
                not isinstance(band, list)
                or len(band) != 2
                or any(isinstance(x, bool) or not isinstance(x, int | float) for x in band)
                or not 0 <= band[0] < band[1] <= 40
            ):
                raise SettingsError(
                    f"speed_bands_kmh.{i}", "must be [low, high] km/h with low < high"
                )
        if not ok:
            raise SettingsError("speed_bands_kmh", "must be 1-12 [low, high] bands in km/h")
