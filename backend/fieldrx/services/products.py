"""The product catalogue of an organisation: the defaults plus the rows it added."""

from __future__ import annotations

from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from fieldrx.agronomy.products import DEFAULT_PRODUCTS
from fieldrx.db.models import Product

ORG_SOURCE = "organisation product"
ORG_PREFIX = "org:"


def product_dict(p: Product) -> dict[str, Any]:
    return {
        "key": f"{ORG_PREFIX}{p.id}",
        "id": p.id,
        "name": p.name,
        "n_pct": p.n_pct,
        "p2o5_pct": p.p2o5_pct,
        "k2o_pct": p.k2o_pct,
        "price_per_t": p.price_per_t,
        "density_kg_l": p.density_kg_l,
        "source": ORG_SOURCE,
        "created_at": p.created_at,
    }


def list_products(session: Session, organisation_id: int) -> list[dict[str, Any]]:
    rows = session.scalars(
        select(Product).where(Product.organisation_id == organisation_id).order_by(Product.name)
    ).all()
    return [d.to_dict() for d in DEFAULT_PRODUCTS] + [product_dict(r) for r in rows]


def resolve_product(session: Session, organisation_id: int, key: str) -> dict[str, Any] | None:
    """The catalogue entry ``key`` names (a default or the organisation's own), or None."""
    for d in DEFAULT_PRODUCTS:
        if d.key == key:
            return d.to_dict()
    if key.startswith(ORG_PREFIX) and key[len(ORG_PREFIX) :].isdigit():
        row = session.get(Product, int(key[len(ORG_PREFIX) :]))
        if row is not None and row.organisation_id == organisation_id:
            out = product_dict(row)
            out.pop("created_at")
            return out
    return None
