"""Liveness and readiness."""

from __future__ import annotations

from fastapi import APIRouter
from sqlalchemy import text

from fieldrx.api.schemas.errors import ERRORS
from fieldrx.api.schemas.health import HealthOut
from fieldrx.auth.deps import SessionDep

router = APIRouter(tags=["health"], responses={503: ERRORS[503]})


@router.get("/health", response_model=HealthOut, openapi_extra={"security": []})
def health(session: SessionDep) -> HealthOut:
    """200 when the API and its database answer (503 when the database does not).

    Versions of the server's components are not disclosed: they only help an attacker
    pick an exploit."""
    session.execute(text("SELECT 1"))
    return HealthOut()
