"""What a machine's implement can do, and whether it can do a job of a given kind.

A job is checked against its machine when it is created and again when it is sent, against
what its kind needs (``fieldrx_edge.jobkinds.registry.Needs``): e.g. seed 002's
depth-controlled seeding a seeder with a depth actuator and a depth sensor, seed 000's
NDVI topdressing an implement that applies fertiliser and canopy (NDVI) sensors. The
meter range (seed 001 eq. 1-3) is checked on the rates themselves
(``services.prescriptions.meter.job_attention``). No database here: the machine's row is read by
the caller.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from fieldrx_edge.jobkinds.registry import kind_of

# "imported": machines created by a TASKDATA import, whose implement is not known
IMPLEMENT_TYPES = ("spreader", "seeder", "seed_fertiliser_drill", "sprayer", "imported")
SENSORS = ("canopy_ndvi", "depth")
FERTILISING = ("spreader", "seed_fertiliser_drill", "sprayer", "imported")
SEEDING = ("seeder", "seed_fertiliser_drill")

# what a missing sensor is called in a refusal
SENSOR_MISSING = {"canopy_ndvi": "no canopy NDVI sensors", "depth": "no depth sensor"}


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
    needs = kind_of(kind).needs
    c = capabilities(caps)
    missing: list[str] = []
    if needs.applies == "fertiliser" and implement_type not in FERTILISING:
        missing.append(f"implement type '{implement_type}' does not apply fertiliser")
    if needs.applies == "seed" and implement_type not in SEEDING and implement_type != "imported":
        missing.append(f"implement type '{implement_type}' does not sow")
    if needs.depth_actuator and not c["depth_actuator"]:
        missing.append("no depth actuator")
    missing += [
        SENSOR_MISSING.get(x, f"no {x} sensor") for x in needs.sensors if x not in c["sensors"]
    ]
    if not missing:
        return None
    return f"{'; '.join(missing)}: a {kind} job needs {needs.text}"
