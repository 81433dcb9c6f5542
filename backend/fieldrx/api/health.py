"""Liveness and readiness."""

from __future__ import annotations

from fastapi import APIRouter
from sqlalchemy import text

from fieldrx.auth.deps import SessionDep

router = APIRouter(tags=["health"])


@router.get("/health")
def health(session: SessionDep) -> dict[str, str]:
    """200 when the API and its database answer (503 when the database does not).

    Versions of the server's components are not disclosed: they only help an attacker
    pick an exploit."""
    session.execute(text("SELECT 1"))
    return {"status": "ok", "database": "ok"}
