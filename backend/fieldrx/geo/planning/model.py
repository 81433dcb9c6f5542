"""What a coverage plan is: swaths with their strip geometry, connections, metrics."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from shapely.geometry import LineString, MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

from .frame import Frame
from .kinematics import Machine

Heading = Literal["longest_edge", "angle", "optimal"]
Corner = Literal["sw", "se", "nw", "ne"]
HEADINGS = ("longest_edge", "angle", "optimal")
CORNERS = ("sw", "se", "nw", "ne")


@dataclass(frozen=True)
class StripGeometry:
    """The strip a swath works: the contract between the planner and the grid.

    Inner swaths (``kind == "inner"``), in the plan's frame (``CoveragePlan.frame``,
    swaths along +x): ``y`` the strip's centre line, ``x0 .. x1`` the swath's extent,
    ``clip`` the piece of (strip & inner region) the swath covers -- cells are clipped
    to it -- and ``full`` the sorted x-intervals ``(n, 2)`` where the whole strip column
    lies inside the region (cells there are plain rectangles). Headland passes: ``band``
    (UTM) is the pass's band that its cells are clipped to, ``ring_pass`` the pass
    number (0 = outermost). The grid reads nothing else of the planner.
    """

    y: float = math.nan
    x0: float = math.nan
    x1: float = math.nan
    clip: Polygon | None = None
    full: np.ndarray | None = None
    band: BaseGeometry | None = None
    ring_pass: int = -1


@dataclass
class Swath:
    """One working pass: ``line`` in driving direction (UTM), its block (headland rings
    have negative blocks), direction (+1 / -1 along the frame's x) and strip geometry."""

    index: int
    line: LineString
    kind: Literal["headland", "inner"]
    block: int
    direction: int
    strip: StripGeometry = field(default_factory=StripGeometry)


@dataclass
class CoveragePlan:
    """A planned field: swaths in driving order, a connection between each consecutive
    pair, the field and inner region (UTM), the frame, and the metrics."""

    heading_deg: float
    swath_width_m: float
    swaths: list[Swath]
    connections: list[LineString]
    field: Polygon | MultiPolygon
    region: Polygon | MultiPolygon
    frame: Frame
    headland_passes: int
    n_blocks: int
    input_field: Polygon | MultiPolygon | None = None
    n_swaths: int = 0
    n_turns: int = 0
    working_length_m: float = 0.0
    nonworking_length_m: float = 0.0
    coverage_pct: float = 0.0
    overlap_pct: float = 0.0
    outside_pct: float = 0.0
    route_outside_m: float = 0.0
    route_in_holes_m: float = 0.0
    warnings: list[str] = field(default_factory=list)
    machine: Machine = field(default_factory=Machine)
    turn_kinds: dict[str, int] = field(default_factory=dict)
    # per connection: "u_turn", "bulb", "fishtail", "transfer" or "routed" (not drivable)
    connection_kinds: list[str] = field(default_factory=list)
    turn_time_s: float = 0.0
    reverse_m: float = 0.0
    required_headland_m: float = 0.0
    undrivable_connections: int = 0
    # field area no cell will hold: what no swath or ring sweeps, and the corner gaps
    uncovered_m2: float = 0.0
    # field area the rounded rings leave to no cell (headland corners cut to the turning
    # radius): a part of uncovered_m2, said apart so the user sees why
    corner_loss_m2: float = 0.0
    # where those corners are (an inner swath may sweep across one, but no cell holds it)
    corner_gaps: BaseGeometry | None = None
    strip_tolerance_m: float = 0.0
    timings_s: dict[str, float] = field(default_factory=dict)

    def route(self) -> LineString:
        """The whole route: swath, connection, swath, ... as one LineString."""
        parts: list[np.ndarray] = []
        for i, s in enumerate(self.swaths):
            parts.append(np.asarray(s.line.coords))
            if i < len(self.connections):
                parts.append(np.asarray(self.connections[i].coords))
        coords = np.concatenate(parts)
        keep = np.ones(len(coords), bool)
        keep[1:] = np.any(np.abs(np.diff(coords, axis=0)) > 1e-9, axis=1)
        coords = coords[keep]
        if len(coords) < 2:
            coords = np.vstack([coords, coords])
        return LineString(coords)

    def metrics(self) -> dict[str, Any]:
        return {
            "n_swaths": self.n_swaths,
            "n_turns": self.n_turns,
            "heading_deg": round(self.heading_deg, 4),
            "working_length_m": round(self.working_length_m, 2),
            "nonworking_length_m": round(self.nonworking_length_m, 2),
            "coverage_pct": round(self.coverage_pct, 4),
            "overlap_pct": round(self.overlap_pct, 4),
            "outside_pct": round(self.outside_pct, 4),
            "route_outside_m": round(self.route_outside_m, 3),
            "route_in_holes_m": round(self.route_in_holes_m, 3),
            "uncovered_m2": round(self.uncovered_m2, 3),
            "corner_loss_m2": round(self.corner_loss_m2, 3),
            "strip_tolerance_m": round(self.strip_tolerance_m, 4),
            "turn_radius_m": self.machine.turn_radius_m,
            "reverse": self.machine.reverse,
            "turn_kinds": dict(self.turn_kinds),
            "turn_time_s": round(self.turn_time_s, 1),
            "reverse_m": round(self.reverse_m, 2),
            "required_headland_m": round(self.required_headland_m, 2),
            "required_headland_passes": self.required_headland_passes,
            "undrivable_connections": self.undrivable_connections,
            "warnings": list(self.warnings),
        }

    @property
    def required_headland_passes(self) -> int:
        """Headland passes whose width holds the turns (0 when there are no turns)."""
        return math.ceil(self.required_headland_m / self.swath_width_m - 1e-9)
