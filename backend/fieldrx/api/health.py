"""Liveness and readiness."""

from __future__ import annotations

from fastapi import APIRouter
from sqlalchemy import text

from fieldrx.auth.deps import SessionDep

router = APIRouter(tags=["health"])


@router.get("/health")
def health(session: SessionDep) -> dict[str, str]:
    """200 when the API and its database answer."""
    version = session.scalar(text("SELECT postgis_lib_version()"))
    return {"status": "ok", "postgis": str(version)}
