"""Coverage path planning: the public entry points of :mod:`fieldrx.geo.planning`.

Seed 001 sec. 1.2 plans parallel swaths (spacing = implement width, base line = the
boundary's longest edge) with a scan line. FieldRx generalises that in
stages, one module each under :mod:`fieldrx.geo.planning`: boundary cleaning,
headland, headings (candidates, bounds, objectives), swaths, decomposition, order,
turns (drivable, turning radius r), metrics, and the planner that chains them. This
module keeps the names the rest of FieldRx imports.

Headings: ``heading_deg`` is the azimuth of the driving line, degrees clockwise from UTM
grid north in [0, 180) (0 = north-south lines, 90 = east-west lines); ``angle_deg``
uses the same convention.
"""

from __future__ import annotations

from .planning.frame import Frame, azimuth_to_phi, phi_to_azimuth
from .planning.headings import (
    Objective,
    SwathCountObjective,
    heading_objective,
    optimal_phi,
    swath_count,
)
from .planning.kinematics import DEFAULT_TURN_RADIUS_M, Machine
from .planning.metrics import swath_footprints
from .planning.model import CORNERS, HEADINGS, Corner, CoveragePlan, Heading, StripGeometry, Swath
from .planning.planner import plan_coverage
from .planning.swaths import (
    STRIP_TOLERANCE_FRACTION,
    STRIP_TOLERANCE_MAX_M,
    default_strip_tolerance,
    n_strips,
)

__all__ = [
    "CORNERS",
    "DEFAULT_TURN_RADIUS_M",
    "HEADINGS",
    "STRIP_TOLERANCE_FRACTION",
    "STRIP_TOLERANCE_MAX_M",
    "Corner",
    "CoveragePlan",
    "Frame",
    "Heading",
    "Machine",
    "Objective",
    "StripGeometry",
    "Swath",
    "SwathCountObjective",
    "azimuth_to_phi",
    "default_strip_tolerance",
    "heading_objective",
    "n_strips",
    "optimal_phi",
    "phi_to_azimuth",
    "plan_coverage",
    "swath_count",
    "swath_footprints",
]
