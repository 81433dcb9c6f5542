"""Coverage plans: parameters in, summary, cells and route out."""

from __future__ import annotations

import datetime as dt
from typing import Literal

from pydantic import Field

from fieldrx.api.schemas.base import Geometry, In, Open, Out
from fieldrx.geo.planning.kinematics import DEFAULT_HEADLAND_PASSES, DEFAULT_TURN_RADIUS_M


class PlanIn(In):
    swath_width_m: float = Field(
        default=2.3, allow_inf_nan=False, description="implement working width w, m"
    )
    cell_length_m: float = Field(
        default=5.0, allow_inf_nan=False, description="cell length L along the path, m"
    )
    heading: Literal["longest_edge", "angle", "optimal"] = "longest_edge"
    angle_deg: float | None = Field(
        default=None, description="swath azimuth, degrees clockwise from north (heading=angle)"
    )
    headland_passes: int = Field(
        default=DEFAULT_HEADLAND_PASSES,
        ge=0,
        le=20,
        description="rings driven round the field before the swaths (0: none; the plan's "
        "metrics say how many its turns need)",
    )
    start_corner: Literal["sw", "se", "nw", "ne"] = "sw"
    headland_order: Literal["first", "last"] = "first"
    min_cell_fraction: float = Field(default=0.1, ge=0, lt=1)
    turn_radius_m: float = Field(
        default=DEFAULT_TURN_RADIUS_M,
        gt=0,
        le=50,
        description="minimum turning radius of the machine, m: turns and headland rings "
        "never curve tighter",
    )
    reverse: bool = Field(default=False, description="the machine may reverse (fishtail turns)")
    pattern: Literal["boustrophedon", "skip", "auto"] = Field(
        default="boustrophedon",
        description="swath order in a block: neighbours, skip-row (U-turns), or the faster",
    )


class PlanParamsOut(Open):
    """The parameters the plan was made with (``PlanIn``, defaults filled in)."""

    swath_width_m: float
    cell_length_m: float
    heading: str
    angle_deg: float | None = None
    headland_passes: int = DEFAULT_HEADLAND_PASSES
    turn_radius_m: float | None = None
    reverse: bool | None = None
    pattern: str | None = None


class PlanMetrics(Open):
    """What the planner measured (``geo.planning``); keys grow with the planner."""

    n_swaths: int | None = None
    n_turns: int | None = None
    n_cells: int | None = None
    heading_deg: float | None = None
    working_length_m: float | None = None
    nonworking_length_m: float | None = None
    coverage_pct: float | None = None
    overlap_pct: float | None = None
    outside_pct: float | None = None
    uncovered_m2: float | None = Field(
        default=None,
        description="field area no cell will hold, m²: what no swath or ring sweeps, and "
        "the headland corners the rounded rings leave out (corner_loss_m2 is a part of it)",
    )
    corner_loss_m2: float | None = Field(
        default=None,
        description="headland corners the rings, rounded to the turning radius, cannot "
        "reach: field area no cell holds, m² (a part of uncovered_m2)",
    )
    turn_time_s: float | None = None
    required_headland_passes: int | None = Field(
        default=None, description="headland passes whose width holds the turns"
    )
    warnings: list[str] | None = None


class PlanOut(Out):
    id: int
    field_id: int
    params: PlanParamsOut
    heading_deg: float | None = Field(description="swath azimuth, degrees clockwise from north")
    n_cells: int
    metrics: PlanMetrics | None
    created_at: dt.datetime | None


class PlanList(Out):
    items: list[PlanOut]
    total: int


class PlanCellProps(Out):
    seq: int = Field(description="position in the path order, 0..n-1")
    swath: int
    index_in_swath: int
    area_m2: float


class PlanCell(Out):
    type: Literal["Feature"] = "Feature"
    id: int
    geometry: Geometry
    properties: PlanCellProps


class PlanCellPage(Out):
    type: Literal["FeatureCollection"] = "FeatureCollection"
    features: list[PlanCell]
    total: int
    limit: int
    offset: int


class RouteProps(Out):
    plan_id: int
    n_swaths: int | None
    n_turns: int | None
    heading_deg: float | None
    working_length_m: float | None
    nonworking_length_m: float | None


class RouteOut(Out):
    type: Literal["Feature"] = "Feature"
    id: int
    geometry: Geometry
    properties: RouteProps
