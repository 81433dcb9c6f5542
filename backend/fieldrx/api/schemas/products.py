"""Fertiliser products and crops the prescription form picks from."""

from __future__ import annotations

import datetime as dt
from typing import Any

from pydantic import Field, model_validator

from fieldrx.api.schemas.base import In, Out


class ProductIn(In):
    name: str = Field(min_length=1, max_length=200)
    n_pct: float = Field(ge=0, le=100, description="N mass fraction in %")
    p2o5_pct: float = Field(default=0.0, ge=0, le=100, description="P2O5 in %")
    k2o_pct: float = Field(default=0.0, ge=0, le=100, description="K2O in %")
    price_per_t: float | None = Field(default=None, ge=0, le=1e9, description="price per tonne")
    density_kg_l: float | None = Field(
        default=None,
        ge=0.05,
        le=5,
        description="a liquid's density in kg/l (lets ISOBUS volume-rate implements take kg/ha)",
    )

    @model_validator(mode="after")
    def _sum(self) -> ProductIn:
        total = self.n_pct + self.p2o5_pct + self.k2o_pct
        if total > 100:
            raise ValueError(f"N + P2O5 + K2O = {total:g} % exceeds 100 %")
        return self


class ProductOut(Out):
    key: str = Field(description="what PrescriptionIn.product_key takes")
    id: int | None = Field(description="the row id of an organisation's product; null: default")
    name: str
    n_pct: float
    p2o5_pct: float
    k2o_pct: float
    price_per_t: float | None
    density_kg_l: float | None = Field(default=None, description="kg/l; null: a solid")
    source: str = Field(description="where the figures come from")
    created_at: dt.datetime | None = None


class SourcedValue(Out):
    value: float
    unit: str
    source: str = Field(description="where the value comes from (publication, seed, assumption)")


class NReference(Out):
    n_rate_kg_ha: float
    yield_t_ha: float
    soil_n_mg_kg: float
    source: str


class CropOut(Out):
    key: str
    name: str
    e_kg_per_100kg: float = Field(description="kg N taken up per 100 kg of yield")
    k_utilisation: float = Field(description="fertiliser N utilisation")
    target_yield_t_ha: float
    source: str = Field(description="source of e_kg_per_100kg (each value's is in values)")
    values: dict[str, SourcedValue] = Field(
        description="every default with its unit and source: target_yield_t_ha, "
        "e_kg_per_100kg (N), uptake_p2o5_kg_per_100kg, uptake_k2o_kg_per_100kg, "
        "k_utilisation, d_intercept_pct / d_slope_pct_mg_kg (seed 001 eq. 20's a, b), "
        "ceiling_n_kg_ha, ceiling_p2o5_kg_ha, ceiling_k2o_kg_ha"
    )
    ceilings_kg_ha: dict[str, float] = Field(description="the crop's default N / P2O5 / K2O caps")
    n_reference: NReference | None = Field(
        description="the published N rate eq. 20's slope is calibrated to (null: the seed's own)"
    )


class CeilingsIn(In):
    """An organisation's plausibility settings; a nutrient left out keeps the crop's value."""

    ceilings_kg_ha: dict[str, dict[str, float | None]] = Field(
        default_factory=dict,
        description='per crop key (or "*" for every crop): {"N": kg/ha, "P2O5": ..., "K2O": ...}',
    )
    curve_share_max: float = Field(
        default=0.25,
        ge=0,
        le=1,
        description="share of a field at a rate curve's cap or floor above which its cells "
        "are flagged and sending needs confirmation",
    )


class CeilingsOut(CeilingsIn):
    effective: dict[str, dict[str, Any]] = Field(
        description="per crop: each nutrient's ceiling in kg/ha and its source"
    )


class Catalogue(Out):
    products: list[ProductOut]
    crops: list[CropOut]


class FormDefaultsOut(Out):
    """What the prescription form starts from on a field (each with where it comes from)."""

    field_id: int
    field_crop: str = Field(description="the field's crop as typed")
    crop: str | None = Field(
        description="crop key matched from the field's crop, else the last prescription's"
    )
    crop_from: str | None = Field(description='"field", "last prescription" or null')
    product_key: str | None = Field(description="the last prescription's product on this field")
    target_yield_t_ha: float | None = Field(description="the last prescription's target yield")
    from_prescription_id: int | None
