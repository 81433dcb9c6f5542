"""Test data shared across test folders (import as `from tests.support import ...`)."""

from __future__ import annotations

# A 35 m x 23 m-ish plot near the demo farm (seed 001's trial plot size), and a larger field.
SMALL_PLOT = {
    "type": "Polygon",
    "coordinates": [
        [
            [112.32000, 32.13000],
            [112.32037, 32.13000],
            [112.32037, 32.13021],
            [112.32000, 32.13021],
            [112.32000, 32.13000],
        ]
    ],
}

FIELD_WITH_HOLE = {
    "type": "Polygon",
    "coordinates": [
        [
            [112.3180, 32.1290],
            [112.3220, 32.1290],
            [112.3220, 32.1320],
            [112.3180, 32.1320],
            [112.3180, 32.1290],
        ],
        [
            [112.3195, 32.1300],
            [112.3195, 32.1308],
            [112.3205, 32.1308],
            [112.3205, 32.1300],
            [112.3195, 32.1300],
        ],
    ],
}


def feature(geometry: dict, **props: object) -> dict:
    return {"type": "Feature", "geometry": geometry, "properties": {"name": "Test field", **props}}


# Seed 001 eq. 1 calibration of the disc spreader (q0 = 237.2 r - 404.4 g/min, 30..130 r/min):
# machines have no default calibration, so tests that create one pass it explicitly.
SEED001_CAL = {
    "kind": "linear",
    "slope_g_min_per_rpm": 237.2,
    "intercept_g_min": -404.4,
    "min_rpm": 30.0,
    "max_rpm": 130.0,
}


# What the sensor job kinds need of a machine (services.implements): seed 000's NDVI
# topdressing a fertiliser implement with canopy sensors, seed 002's seeding a seeder with
# a depth actuator and depth sensor.
NDVI_SPREADER = {"implement_type": "spreader", "capabilities": {"sensors": ["canopy_ndvi"]}}
DEPTH_SEEDER = {
    "implement_type": "seeder",
    "capabilities": {"depth_actuator": True, "sensors": ["depth"]},
}
BOTH_KINDS = {
    "implement_type": "seed_fertiliser_drill",
    "capabilities": {"depth_actuator": True, "sensors": ["canopy_ndvi", "depth"]},
}


def machine_body(name: str = "Spreader", width_m: float = 2.3, **extra: object) -> dict:
    """A POST /machines body with an explicit calibration and lag (seed 001: 1.52 s)."""
    return {"name": name, "width_m": width_m, "lag_s": 1.52, "calibration": SEED001_CAL, **extra}


def time_scale() -> float:
    """How much longer than on a quiet machine a wait on another process may take.

    FIELDRX_TEST_TIME_SCALE when set; else 2 plus the run-queue length per core (the
    1-minute load average over the core count), at most 12: with 8 busy processes on 2
    cores a server's start takes about 5x as long as on a quiet machine. Waits end as
    soon as their readiness signal arrives, so a generous scale only delays failures.
    """
    import os

    env = os.environ.get("FIELDRX_TEST_TIME_SCALE")
    if env:
        return max(1.0, float(env))
    return min(12.0, 2.0 + os.getloadavg()[0] / (os.cpu_count() or 1))


def scaled(seconds: float) -> float:
    """A deadline of `seconds` on a quiet machine, stretched by time_scale()."""
    return seconds * time_scale()
