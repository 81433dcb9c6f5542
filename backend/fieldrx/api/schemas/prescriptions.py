"""Prescriptions: build parameters, edits, versions, cells."""

from __future__ import annotations

import datetime as dt
from typing import Annotated, Any, Literal

from fieldrx_edge.rateunits.registry import names as unit_names
from fieldrx_edge.rateunits.registry import unit_of
from pydantic import AfterValidator, Field, WithJsonSchema, model_validator

from fieldrx.agronomy.interpolate import DEFAULT_METHOD
from fieldrx.agronomy.ratemodels.registry import DEFAULT_MODEL, accepted_names, rate_models
from fieldrx.api.schemas.base import Geometry, In, Open, Out

# a model of agronomy.ratemodels (or an alias); the OpenAPI enum is the registry's list.
# Not validated here: an unknown model is answered by the prescription service, whose
# message names the known ones.
RateModelName = Annotated[str, WithJsonSchema({"type": "string", "enum": accepted_names()})]
MODEL_DOC = " | ".join(rate_models().names()) + (
    f" (aliases: {', '.join(a for m in rate_models() for a in m.aliases)})"
)
PARAMS_DOC = "; ".join(f"{m.name}: {', '.join(p.name for p in m.params)}" for m in rate_models())


def _known_unit(v: str) -> str:
    unit_of(v)  # RateUnitError (a ValueError) names the known units: a 422
    return v


# a unit of fieldrx_edge.rateunits; the OpenAPI enum is the registry's list
RateUnitName = Annotated[
    str, AfterValidator(_known_unit), WithJsonSchema({"type": "string", "enum": list(unit_names())})
]


class PrescriptionIn(In):
    name: str = Field(default="", max_length=200)
    product: str = Field(default="", max_length=200)
    model: RateModelName = Field(default=DEFAULT_MODEL, description=MODEL_DOC)
    params: dict[str, Any] = Field(default_factory=dict, description=PARAMS_DOC)
    interpolation: Literal["cell_mean", "idw", "kriging"] = Field(
        default=DEFAULT_METHOD, description="cell values from the samples (idw: inverse distance)"
    )
    interpolation_params: dict[str, Any] = Field(
        default_factory=dict,
        description="idw: power, radius_m, k; kriging: variogram_model, nlags, max_distance_m",
    )
    fallback_rate_kg_ha: float | None = Field(default=None, ge=0)
    machine_id: int | None = None
    # physical bounds: degenerate values (5e-324 m) only make rate = flow / (w v) overflow
    speed_min_kmh: float | None = Field(default=None, ge=0.036, le=108)
    speed_max_kmh: float | None = Field(default=None, ge=0.036, le=108)
    width_m: float | None = Field(default=None, ge=0.05, le=60)
    calibration: dict[str, Any] | None = None
    crop: str | None = Field(
        default=None,
        description="a crop key of GET /products: its defaults (target yield, e, k, eq. 20's "
        "a and b) fill the nutrient-balance parameters not given, and its ceilings are "
        "checked; without it the field's crop is used when it names one",
    )
    product_key: str | None = Field(
        default=None,
        description="a product key of GET /products: names the product, gives n_fraction "
        "(models that take the crop's defaults) and the version's nutrient and cost figures",
    )
    clamp_min_kg_ha: float | None = Field(
        default=None, ge=0, description="raise model rates below this (cells flagged, counted)"
    )
    clamp_max_kg_ha: float | None = Field(
        default=None, ge=0, description="lower model rates above this (cells flagged, counted)"
    )
    class_count: int = Field(default=6, ge=1, le=20, description="legend classes of version 1")
    note: str = Field(default="", max_length=2000, description="note of version 1")
    rate_unit: RateUnitName = Field(
        default="kg/ha",
        description="the unit the prescription is given and sent in (GET /rate-units): "
        "l/ha: a liquid product (one with a density, product_key or lot) applied by volume; "
        "the rates are worked out in kg/ha and its job packages and ISOXML carry the unit "
        "(l/ha: DDI 1)",
    )
    lot: dict[str, float] | None = Field(
        default=None,
        description="values of the product lot the rate unit converts through (GET "
        "/rate-units: e.g. density_kg_l); they fill in for the catalogue product's, and one "
        "that contradicts it is refused",
    )

    @model_validator(mode="after")
    def _clamp_order(self) -> PrescriptionIn:
        lo, hi = self.clamp_min_kg_ha, self.clamp_max_kg_ha
        if lo is not None and hi is not None and lo > hi:
            raise ValueError(f"clamp_min_kg_ha {lo:g} exceeds clamp_max_kg_ha {hi:g}")
        return self


class CellEdit(In):
    seq: int = Field(ge=0)
    rate_kg_ha: float = Field(ge=0)


class EditIn(In):
    cells: list[CellEdit] | None = None
    zone: Geometry | None = Field(default=None, description="GeoJSON Polygon (lon/lat)")
    rate_kg_ha: float | None = Field(default=None, ge=0, description="rate of the zone")
    note: str = Field(default="", max_length=2000)
    based_on_version: int | None = Field(
        default=None, ge=1, description="the version edited (default: the current one)"
    )

    @model_validator(mode="after")
    def _one_kind(self) -> EditIn:
        if (self.cells is None) == (self.zone is None):
            raise ValueError("give either cells [{seq, rate_kg_ha}] or zone + rate_kg_ha")
        if self.zone is not None and self.rate_kg_ha is None:
            raise ValueError("a zone edit needs rate_kg_ha")
        return self


class Histogram(Open):
    """Whole-field, area-weighted: ``counts[i]`` cells and ``area_m2[i]`` between
    ``edges_kg_ha[i]`` and ``edges_kg_ha[i+1]``."""

    edges_kg_ha: list[float]
    counts: list[int]
    area_m2: list[float]


class Attention(Open):
    """Cells the machine will not apply as prescribed (meter range) or with a fallback rate."""

    flags: list[str] = Field(default_factory=list)
    count: int = 0
    area_m2: float = 0.0
    area_ha: float = 0.0
    seq: list[int] | None = None


class ClampReport(Open):
    """The agronomist's min / max and what it changed when the version was built."""

    min_kg_ha: float | None = None
    max_kg_ha: float | None = None
    raised: int = 0
    lowered: int = 0
    count: int = 0
    area_m2: float = 0.0
    model_min_kg_ha: float | None = None
    model_max_kg_ha: float | None = None
    seq: list[int] | None = None


class ClassRow(Open):
    """One legend class of the zones table: its rate range, cells, ha and t of product."""

    class_: int = Field(alias="class")
    from_kg_ha: float
    to_kg_ha: float
    n_cells: int
    area_ha: float
    product_t: float


class LegendClasses(Open):
    """The version's legend classes (fixed with it) and its zones table."""

    breaks_kg_ha: list[float]
    source: str
    table: list[ClassRow]


class RxSummary(Open):
    """A version's whole-field figures (``agronomy.prescription.summarize``) as stored with
    it; edits add ``edited_cells`` and ``based_on_version``."""

    n_cells: int = 0
    area_m2: float = 0.0
    area_ha: float = 0.0
    product_kg: float = 0.0
    rate_mean_kg_ha: float | None = None
    rate_min_kg_ha: float | None = None
    rate_max_kg_ha: float | None = None
    histogram: Histogram | None = None
    flagged: dict[str, int] | None = None
    flagged_area_m2: dict[str, float] | None = None
    n_flagged: int | None = None
    attention: Attention | None = None
    flagged_seq: list[int] | None = None
    interpolation: dict[str, Any] | None = None
    meter: dict[str, Any] | None = None
    product_t: float | None = None
    nutrients_kg: dict[str, float] | None = Field(default=None, description="N, P2O5, K2O")
    nutrients_kg_ha: dict[str, float] | None = None
    cost: float | None = Field(default=None, description="product t x price per t")
    product: dict[str, Any] | None = Field(default=None, description="the product used")
    crop: dict[str, Any] | None = None
    param_sources: dict[str, str] | None = Field(
        default=None, description="where each model parameter came from"
    )
    param_origin: dict[str, str] | None = Field(
        default=None,
        description='per model parameter: "default" (the crop\'s / product\'s), "override" '
        '(given, differs from the default) or "given" (no default)',
    )
    crop_from: str | None = Field(default=None, description='"request", "field" or null')
    plausibility: dict[str, Any] | None = Field(
        default=None,
        description="ceilings (kg/ha per nutrient, with sources), the product's fractions, "
        "above_ceiling {count, area_m2, seq, nutrients}, curve_limits {cap, floor: share}",
    )
    clamp: ClampReport | None = None
    classes: LegendClasses | None = None


class RxStats(Out):
    """Counts derived from the current version's flags (not copies of ``summary``)."""

    out_of_meter_range_count: int
    no_data_count: int
    attention_count: int
    attention_area_m2: float
    kriging_cv_rmse: float | None = Field(
        default=None, description="leave-one-out RMSE of the kriging interpolation"
    )


class VersionRef(Out):
    version: int
    note: str
    created_at: dt.datetime | None


class PrescriptionOut(Out):
    id: int
    plan_id: int
    machine_id: int | None
    name: str
    product: str
    model: str
    params: dict[str, Any] = Field(description="the rate model's parameters")
    interpolation: str | None
    interpolation_params: dict[str, Any]
    fallback_rate_kg_ha: float | None
    meter: dict[str, Any] | None = Field(description="the meter the rates were checked against")
    rate_unit: str = Field(
        default="kg/ha", description="kg/ha, or l/ha: sent to machines by volume (DDI 1)"
    )
    density_kg_l: float | None = Field(
        default=None, description="the product's density: l/ha = kg/ha / density"
    )
    lot: dict[str, float] = Field(
        default_factory=dict, description="the product lot values the rate unit converts through"
    )
    kg_per_unit: float | None = Field(
        default=None,
        description="kg/ha in 1 rate_unit/ha (rates shown in the unit are kg/ha / this); "
        "null: the lot does not say",
    )
    current_version: int
    versions: list[VersionRef]
    summary: RxSummary = Field(description="the current version's summary")
    stats: RxStats
    created_at: dt.datetime | None


class EditOut(PrescriptionOut):
    edited_cells: int
    new_version: int


class PrescriptionList(Out):
    items: list[PrescriptionOut]
    total: int


class VersionOut(Out):
    version: int
    note: str
    created_at: dt.datetime | None
    created_by: int | None
    summary: RxSummary


class VersionDetail(VersionOut):
    prescription_id: int


class VersionList(Out):
    items: list[VersionOut]
    total: int
    current_version: int


class RxCellProps(Out):
    seq: int
    swath: int
    area_m2: float
    rate_kg_ha: float
    flags: list[str]
    out_of_meter_range: bool = Field(
        description="outside what the machine meters at the planned speeds (stored as asked)"
    )
    fallback: bool = Field(description="no sample near enough: the rate is the fallback rate")
    source_value: float | None


class RxCell(Out):
    type: Literal["Feature"] = "Feature"
    id: int
    geometry: Geometry
    properties: RxCellProps


class RxCellPage(Out):
    type: Literal["FeatureCollection"] = "FeatureCollection"
    features: list[RxCell]
    total: int
    version: int = Field(description="the version these cells belong to")
    limit: int
    offset: int


class SoilZonesIn(PrescriptionIn):
    """A zone prescription from soil samples: the model's input property interpolated
    onto the plan's cells, then zoned like imagery NDVI zones."""

    k: int = Field(default=4, ge=2, le=12, description="number of zones")
    min_area_m2: float = Field(
        default=0.0, ge=0, description="patches of a zone smaller than this join a neighbour"
    )


class VersionPatch(In):
    """A version's note and legend classes (its rates never change)."""

    note: str | None = Field(default=None, max_length=2000)
    class_count: int | None = Field(default=None, ge=1, le=20)
    breaks_kg_ha: list[float] | None = Field(default=None, min_length=2, max_length=21)

    @model_validator(mode="after")
    def _one_classes(self) -> VersionPatch:
        if self.class_count is not None and self.breaks_kg_ha is not None:
            raise ValueError("give a class count or class breaks, not both")
        return self


class CurrentIn(In):
    version: int = Field(ge=1, description="the version that becomes current (undo / redo)")


class VersionDiff(Out):
    """What changed from version ``from_version`` to ``to_version`` (b - a)."""

    from_version: int
    to_version: int
    cells_changed: int
    area_changed_m2: float
    area_changed_ha: float
    product_kg_delta: float
    cost_delta: float | None
    rate_mean_delta_kg_ha: float | None
    max_increase_kg_ha: float
    max_decrease_kg_ha: float
    seq: list[int] = Field(description="the first 1000 changed cells")
