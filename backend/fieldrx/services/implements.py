"""What a machine's implement can do, and whether it can do a job of a given kind.

A job is checked against its machine when it is created and again when it is sent: a
seeding-depth job (seed 002) needs a seeder with a depth actuator and a depth sensor, an
NDVI topdressing job (seed 000) an implement that applies fertiliser and canopy (NDVI)
sensors. The meter range (seed 001 eq. 1-3) is checked on the rates themselves
(``services.prescriptions.meter.job_attention``). No database here: the machine's row is read by
the caller.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

# "imported": machines created by a TASKDATA import, whose implement is not known
IMPLEMENT_TYPES = ("spreader", "seeder", "seed_fertiliser_drill", "sprayer", "imported")
SENSORS = ("canopy_ndvi", "depth")
FERTILISING = ("spreader", "seed_fertiliser_drill", "sprayer", "imported")
SEEDING = ("seeder", "seed_fertiliser_drill")

KIND_NEEDS = {
    "prescription_map": "an implement that meters fertiliser",
    "ndvi_topdress": "an implement that applies fertiliser and canopy NDVI sensors "
    "(capabilities.sensors: canopy_ndvi), seed 000",
    "seeding_depth": "a seeder with a depth actuator (capabilities.depth_actuator) and a "
    "depth sensor (capabilities.sensors: depth), seed 002",
}


def capabilities(raw: Mapping[str, Any] | None) -> dict[str, Any]:
    """A machine's stored capabilities with the defaults of what it did not declare."""
    raw = dict(raw or {})
    return {
        "sections": int(raw.get("sections") or 1),
        "depth_actuator": bool(raw.get("depth_actuator", False)),
        "sensors": sorted(set(raw.get("sensors") or ())),
    }


def job_refusal(kind: str, implement_type: str, caps: Mapping[str, Any] | None) -> str | None:
    """Why a machine with this implement and these capabilities cannot do a ``kind`` job
    (None: it can). The reason names what is missing and what the kind needs."""
    c = capabilities(caps)
    missing: list[str] = []
    if kind == "prescription_map":
        if implement_type not in FERTILISING:
            missing.append(f"implement type '{implement_type}' does not apply fertiliser")
    elif kind == "ndvi_topdress":
        if implement_type not in FERTILISING:
            missing.append(f"implement type '{implement_type}' does not apply fertiliser")
        if "canopy_ndvi" not in c["sensors"]:
            missing.append("no canopy NDVI sensors")
    elif kind == "seeding_depth":
        if implement_type not in SEEDING and implement_type != "imported":
            missing.append(f"implement type '{implement_type}' does not sow")
        if not c["depth_actuator"]:
            missing.append("no depth actuator")
        if "depth" not in c["sensors"]:
            missing.append("no depth sensor")
    if not missing:
        return None
    return f"{'; '.join(missing)}: a {kind} job needs {KIND_NEEDS[kind]}"
