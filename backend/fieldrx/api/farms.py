"""Farms: a named group of fields."""

from __future__ import annotations

from fastapi import APIRouter, Query
from sqlalchemy import func, select

from fieldrx.api.common import get_scoped
from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.farms import FarmIn, FarmList, FarmOut, FarmPatch
from fieldrx.auth.deps import SessionDep, UserDep, WriterDep
from fieldrx.db.models import Farm

router = APIRouter(prefix="/farms", tags=["farms"], responses=ERRORS)


@router.get("", response_model=FarmList)
def list_farms(
    principal: UserDep,
    session: SessionDep,
    q: str | None = Query(default=None, description="case-insensitive name filter"),
    limit: int = Query(default=100, ge=1, le=1000),
    offset: int = Query(default=0, ge=0),
) -> FarmList:
    stmt = select(Farm).where(Farm.organisation_id == principal.organisation_id)
    if q:
        stmt = stmt.where(Farm.name.ilike(f"%{q}%"))
    total = session.scalar(select(func.count()).select_from(stmt.subquery())) or 0
    rows = session.scalars(stmt.order_by(Farm.id).limit(limit).offset(offset))
    return FarmList(
        items=[FarmOut.model_validate(r, from_attributes=True) for r in rows], total=total
    )


@router.post("", response_model=FarmOut, status_code=201)
def create_farm(body: FarmIn, principal: WriterDep, session: SessionDep) -> FarmOut:
    farm = Farm(organisation_id=principal.organisation_id, name=body.name, notes=body.notes)
    session.add(farm)
    session.commit()
    return FarmOut.model_validate(farm, from_attributes=True)


@router.get("/{farm_id:int}", response_model=FarmOut)
def get_farm(farm_id: int, principal: UserDep, session: SessionDep) -> FarmOut:
    return FarmOut.model_validate(
        get_scoped(session, Farm, farm_id, principal), from_attributes=True
    )


@router.patch("/{farm_id:int}", response_model=FarmOut)
def update_farm(
    farm_id: int, body: FarmPatch, principal: WriterDep, session: SessionDep
) -> FarmOut:
    farm = get_scoped(session, Farm, farm_id, principal)
    for key, value in body.model_dump(exclude_unset=True).items():
        if value is not None:
            setattr(farm, key, value)
    session.commit()
    return FarmOut.model_validate(farm, from_attributes=True)


@router.delete("/{farm_id:int}", status_code=204)
def delete_farm(farm_id: int, principal: WriterDep, session: SessionDep) -> None:
    """Delete a farm; its fields stay, without a farm."""
    session.delete(get_scoped(session, Farm, farm_id, principal))
    session.commit()
