"""Liveness and readiness."""

from __future__ import annotations

from typing import Literal

from fieldrx.api.schemas.base import Out


class HealthOut(Out):
    status: Literal["ok"] = "ok"
    database: Literal["ok"] = "ok"
