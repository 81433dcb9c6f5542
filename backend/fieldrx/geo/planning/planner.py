"""The coverage planner: a short chain of the stages in this package.

boundary (clean, report changes) -> headland (rings rounded to the turning radius, the
inner region less what they sweep) -> headings (the driving direction) -> swaths +
decomposition (strips, pieces, blocks) -> order (rings and blocks in driving order) ->
turns (drivable connections) -> metrics.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Literal

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

from .. import PlanningError
from ..route import FieldRouter
from .boundary import parts, polygonal, simplified, snapped
from .decomposition import layout
from .frame import azimuth_to_phi, frame_for, phi_to_azimuth
from .headings import longest_edge_phi, optimal_phi
from .headland import carve, corner_gaps, headland_rings, inner_region
from .kinematics import DEFAULT_HEADLAND_PASSES, DEFAULT_TURN_RADIUS_M, Machine
from .metrics import fill_metrics, turn_warnings
from .model import CORNERS, HEADINGS, Corner, CoveragePlan, Heading
from .order import PATTERNS, block_sequences, order_swaths
from .swaths import default_strip_tolerance, holes_of
from .turns import connect

# Headland rings are rounded to the turning radius (headland.drivable_centre); False
# keeps the mitred offsets' sharp corners (a machine that can pivot, or a comparison).
ROUND_HEADLAND_RINGS = True


def plan_coverage(
    boundary_utm: Polygon | MultiPolygon,
    swath_width_m: float = 2.3,
    heading: Heading = "longest_edge",
    angle_deg: float | None = None,
    headland_passes: int = DEFAULT_HEADLAND_PASSES,
    start_corner: Corner = "sw",
    headland_order: Literal["first", "last"] = "first",
    simplify_tolerance_m: float | None = None,
    strip_tolerance_m: float | None = None,
    turn_radius_m: float = DEFAULT_TURN_RADIUS_M,
    reverse: bool = False,
    pattern: str = "boustrophedon",
) -> CoveragePlan:
    """Plan the coverage path of a field given in UTM metres (see module docstring).

    ``strip_tolerance_m``: widest uncovered strip not worth a swath (default
    :func:`default_strip_tolerance`, 1 % of w and at most 5 cm). ``turn_radius_m`` and
    ``reverse`` describe the machine (:class:`~.planning.kinematics.Machine`): turns
    between swaths are drivable paths (:mod:`.planning.turns`). ``pattern``:
    ``boustrophedon`` (neighbouring swaths in turn), ``skip`` (skip-row: swaths s apart,
    s = ceil(2r / w), so every turn is a U-turn) or ``auto`` (per block, the one whose
    turns take less time).

    No GEOS exception reaches the caller: when the geometry engine fails on a boundary
    (a TopologyException on a real traced field), the boundary is snap-rounded to a
    1 mm grid and planned again, with a warning in the plan; if that fails too, the
    answer is a PlanningError saying so.
    """
    st = _settings(
        swath_width_m,
        heading,
        angle_deg,
        headland_passes,
        start_corner,
        headland_order,
        simplify_tolerance_m,
        strip_tolerance_m,
        Machine(turn_radius_m=turn_radius_m, reverse=bool(reverse)),
        pattern,
    )
    warnings: list[str] = []
    fld_in = polygonal(boundary_utm, warnings)
    try:
        plan = _plan_field(fld_in, st, list(warnings))
    except shapely.errors.GEOSException as exc:
        warnings.append(
            f"the geometry engine failed on this boundary ({exc}); it was snapped to a "
            "1 mm grid and planned again"
        )
        try:
            plan = _plan_field(snapped(fld_in), st, warnings)
        except shapely.errors.GEOSException as exc2:
            raise PlanningError(
                "the geometry engine cannot process this boundary, even snapped to a 1 mm "
                f"grid ({exc2}); simplify or redraw it"
            ) from exc2
    plan.input_field = fld_in
    return plan


@dataclass(frozen=True)
class _Settings:
    w: float
    heading: str
    angle_deg: float | None
    h: int
    start_corner: str
    headland_order: str
    simplify_tol: float
    tol: float
    machine: Machine
    pattern: str


def _settings(
    swath_width_m: float,
    heading: str,
    angle_deg: float | None,
    headland_passes: int,
    start_corner: str,
    headland_order: str,
    simplify_tolerance_m: float | None,
    strip_tolerance_m: float | None,
    machine: Machine,
    pattern: str,
) -> _Settings:
    """The validated parameters (PlanningError says which one is wrong and why)."""
    w = float(swath_width_m)
    if not math.isfinite(w) or w <= 0:
        raise PlanningError(f"swath_width_m must be > 0, got {swath_width_m}")
    if heading not in HEADINGS:
        raise PlanningError(f"heading must be one of {HEADINGS}, got {heading!r}")
    if start_corner not in CORNERS:
        raise PlanningError(f"start_corner must be one of {CORNERS}, got {start_corner!r}")
    if headland_order not in ("first", "last"):
        raise PlanningError(f"headland_order must be 'first' or 'last', got {headland_order!r}")
    if int(headland_passes) != headland_passes or headland_passes < 0:
        raise PlanningError(f"headland_passes must be an integer >= 0, got {headland_passes}")
    h = int(headland_passes)
    tol = default_strip_tolerance(w) if strip_tolerance_m is None else float(strip_tolerance_m)
    if not math.isfinite(tol) or not 0.0 <= tol < 0.5 * w:
        raise PlanningError(f"strip_tolerance_m must be in [0, w/2), got {strip_tolerance_m}")
    if heading == "angle":
        if angle_deg is None or not math.isfinite(float(angle_deg)):
            raise PlanningError("heading 'angle' needs angle_deg (degrees clockwise from north)")
    if pattern not in PATTERNS:
        raise PlanningError(f"pattern must be one of {PATTERNS}, got {pattern!r}")
    return _Settings(
        w,
        heading,
        None if angle_deg is None else float(angle_deg),
        h,
        start_corner,
        headland_order,
        min(0.25 * w, 1.0) if simplify_tolerance_m is None else float(simplify_tolerance_m),
        tol,
        machine,
        pattern,
    )


def _corner_point(geom: BaseGeometry, corner: str) -> np.ndarray:
    x0, y0, x1, y1 = geom.bounds
    return np.array([x0 if corner[1] == "w" else x1, y0 if corner[0] == "s" else y1])


@contextmanager
def _timed(timings: dict[str, float], stage: str) -> Iterator[None]:
    t = time.perf_counter()
    yield
    timings[stage] = time.perf_counter() - t


def _heading_phi(fld: BaseGeometry, region: BaseGeometry, st: _Settings) -> float:
    if st.heading == "angle":
        return azimuth_to_phi(float(st.angle_deg))  # type: ignore[arg-type]
    if st.heading == "longest_edge" or region.is_empty:
        return longest_edge_phi(fld)
    return optimal_phi(region, fld, st.w, tol=st.tol)[0]


def _corner_warning(fld: BaseGeometry, lost: float, m: Machine, warnings: list[str]) -> None:
    """Say how much of the field the rounded rings leave unworked (``lost`` m²) when it
    is more than 1 m² or 0.1 % of the field."""
    if lost > 1e-3 * max(fld.area, 1.0) or lost > 1.0:
        warnings.append(
            f"headland corners rounded to the {m.turn_radius_m:g} m turning radius leave "
            f"{lost:.0f} m² of the headland unworked ({100 * lost / fld.area:.2f} % of the "
            "field; counted as uncovered)"
        )


def _plan_field(fld_in: Polygon | MultiPolygon, st: _Settings, warnings: list[str]) -> CoveragePlan:
    """Plan one (clean) field; GEOS errors propagate to :func:`plan_coverage`."""
    w = st.w
    timings: dict[str, float] = {}
    with _timed(timings, "validate"):
        fld = simplified(fld_in, st.simplify_tol, warnings)
        region, h = inner_region(fld, w, st.h, warnings)
    with _timed(timings, "headland"):
        if ROUND_HEADLAND_RINGS:
            rings = headland_rings(fld, w, h, st.machine.turn_radius_m, warnings)
            region, dropped = carve(region, rings, w)
            gaps = shapely.union_all([corner_gaps(fld, w, h, rings), dropped])
            _corner_warning(fld, gaps.area, st.machine, warnings)
        else:
            rings, gaps = headland_rings(fld, w, h), Polygon()
    with _timed(timings, "heading"):
        phi = _heading_phi(fld, region, st)
    with _timed(timings, "swaths"):
        frame = frame_for(fld if region.is_empty else region, phi)
        parts_rot = [frame.fwd_geom(p) for p in parts(region)]
        holes_rot = frame.fwd_geom(holes_of(fld))
        subs, blocks = layout(parts_rot, w, with_full=True, holes_rot=holes_rot, tol=st.tol)
        blocks = block_sequences(subs, blocks, w, st.machine, h * w, st.pattern)
    with _timed(timings, "order_route"):
        router = FieldRouter(fld, avoid=region if h else None)
        lead = 2.0 * st.machine.turn_radius_m
        start = _corner_point(fld, st.start_corner)
        first = st.headland_order == "first"
        swaths = order_swaths(subs, blocks, rings, frame, start, router.distance, first, lead)
    with _timed(timings, "turns"):
        turns = connect(swaths, router.path, st.machine, fld, region, h * w, w)
        turn_warnings(turns, st.machine, w, h, warnings)
    m = st.machine
    plan = CoveragePlan(
        heading_deg=phi_to_azimuth(phi),
        swath_width_m=w,
        swaths=swaths,
        connections=[c.line for c in turns.connections],
        field=fld,
        region=region,
        frame=frame,
        input_field=fld_in,
        headland_passes=h,
        n_blocks=len(blocks),
        strip_tolerance_m=st.tol,
        warnings=warnings,
        machine=m,
        turn_kinds=dict(turns.kinds),
        connection_kinds=[c.kind for c in turns.connections],
        turn_time_s=sum(
            m.time_s(c.line.length - c.reverse_m, c.reverse_m, c.cusps) for c in turns.connections
        ),
        reverse_m=sum(c.reverse_m for c in turns.connections),
        required_headland_m=turns.required_headland_m,
        undrivable_connections=turns.undrivable,
        corner_loss_m2=float(gaps.area),
        corner_gaps=gaps,
    )
    with _timed(timings, "metrics"):
        fill_metrics(plan)
    plan.timings_s = timings
    return plan
