"""Fertiliser products and crop defaults for the prescription form."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter
from sqlalchemy import select

from fieldrx.agronomy.products import CROPS
from fieldrx.api.common import ApiError, get_scoped
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.products import Catalogue, ProductIn, ProductOut
from fieldrx.auth.deps import SessionDep, UserDep, WriterDep
from fieldrx.db.models import Product
from fieldrx.services import products as svc

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
