"""Fertiliser products and crops the prescription form picks from."""

from __future__ import annotations

import datetime as dt

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


class CropOut(Out):
    key: str
    name: str
    e_kg_per_100kg: float = Field(description="kg N taken up per 100 kg of yield")
    k_utilisation: float = Field(description="fertiliser N utilisation")
    target_yield_t_ha: float
    source: str


class Catalogue(Out):
    products: list[ProductOut]
    crops: list[CropOut]
