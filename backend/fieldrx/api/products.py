"""Fertiliser products and crop defaults for the prescription form."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter
from sqlalchemy import select

from fieldrx.agronomy.crops import CROPS, NUTRIENTS
from fieldrx.agronomy.plausibility import DEFAULT_CURVE_SHARE_MAX, resolve_ceilings
from fieldrx.api.common import ApiError, get_scoped
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.products import (
    Catalogue,
    CeilingsIn,
    CeilingsOut,
    FormDefaultsOut,
    ProductIn,
    ProductOut,
)
from fieldrx.auth.deps import AdminDep, SessionDep, UserDep, WriterDep
from fieldrx.db.models import Field, Organisation, Product
from fieldrx.services import products as svc
from fieldrx.services.prescriptions.params import form_defaults

router = APIRouter(tags=["products"], responses=ERRORS)


@router.get("/products", response_model=Catalogue)
def catalogue(principal: UserDep, session: SessionDep) -> dict[str, Any]:
    """Default products and crops (each with its ``source``) and the organisation's own
    products (source "organisation product")."""
    return {
        "products": svc.list_products(session, principal.organisation_id),
        "crops": [c.to_dict() for c in CROPS],
    }


@router.post("/products", status_code=201, response_model=ProductOut)
def add_product(body: ProductIn, principal: WriterDep, session: SessionDep) -> dict[str, Any]:
    """Add a product to the organisation's catalogue (409 when the name is taken)."""
    taken = session.scalar(
        select(Product.id).where(
            Product.organisation_id == principal.organisation_id, Product.name == body.name
        )
    )
    if taken is not None:
        raise ApiError(409, f"product {body.name!r} already exists (id {taken})", where="name")
    row = Product(organisation_id=principal.organisation_id, **body.model_dump())
    session.add(row)
    session.commit()
    return svc.product_dict(row)


@router.delete("/products/{product_id:int}", status_code=204)
def delete_product(product_id: int, principal: WriterDep, session: SessionDep) -> None:
    """Remove an organisation's product; prescriptions keep the copy they were built with."""
    session.delete(get_scoped(session, Product, product_id, principal))
    session.commit()


def _ceilings_out(settings: dict[str, Any]) -> dict[str, Any]:
    ceilings = dict(settings.get("ceilings_kg_ha") or {})
    return {
        "ceilings_kg_ha": ceilings,
        "curve_share_max": float(settings.get("curve_share_max", DEFAULT_CURVE_SHARE_MAX)),
        "effective": {c.key: resolve_ceilings(c, ceilings) for c in CROPS},
    }


@router.get("/ceilings", response_model=CeilingsOut)
def get_ceilings(principal: UserDep, session: SessionDep) -> dict[str, Any]:
    """The organisation's plausibility settings and, per crop, the ceilings a prescription
    is checked against (organisation over the crop's published default, with sources)."""
    org = session.get(Organisation, principal.organisation_id)
    return _ceilings_out(dict((org.agronomy if org else None) or {}))


@router.put("/ceilings", response_model=CeilingsOut)
def put_ceilings(body: CeilingsIn, principal: AdminDep, session: SessionDep) -> dict[str, Any]:
    """Set the organisation's ceilings (e.g. a regional legal N limit) and the share of a
    field allowed at a rate curve's cap or floor; checked on prescriptions made after."""
    keys = {c.key for c in CROPS} | {"*"}
    for crop, caps in body.ceilings_kg_ha.items():
        if crop not in keys:
            raise ApiError(
                422,
                f"unknown crop {crop!r} (expected one of {sorted(keys)})",
                where=f"ceilings_kg_ha.{crop}",
            )
        for n, v in caps.items():
            if n not in NUTRIENTS:
                raise ApiError(
                    422,
                    f"unknown nutrient {n!r} (expected one of {list(NUTRIENTS)})",
                    where=f"ceilings_kg_ha.{crop}.{n}",
                )
            if v is not None and not 0 <= v <= 10000:
                raise ApiError(
                    422,
                    f"ceiling must be 0..10000 kg/ha, got {v!r}",
                    where=f"ceilings_kg_ha.{crop}.{n}",
                )
    org = session.get(Organisation, principal.organisation_id)
    if org is None:
        raise ApiError(404, "organisation not found")
    org.agronomy = {**(org.agronomy or {}), **body.model_dump()}
    session.commit()
    return _ceilings_out(dict(org.agronomy))


@router.get("/fields/{field_id:int}/rx-defaults", response_model=FormDefaultsOut)
def rx_defaults(field_id: int, principal: UserDep, session: SessionDep) -> dict[str, Any]:
    """The prescription form's starting values on this field: its crop, and the product and
    target yield of the field's last prescription."""
    return form_defaults(session, get_scoped(session, Field, field_id, principal))
