"""Farms: a named group of fields."""

from __future__ import annotations

import datetime as dt

from pydantic import Field

from fieldrx.api.schemas.base import In, Out


class FarmIn(In):
    name: str = Field(min_length=1, max_length=200)
    notes: str = Field(default="", max_length=10_000)


class FarmPatch(In):
    name: str | None = Field(default=None, min_length=1, max_length=200)
    notes: str | None = Field(default=None, max_length=10_000)


class FarmOut(Out):
    id: int
    name: str
    notes: str
    created_at: dt.datetime


class FarmList(Out):
    items: list[FarmOut]
    total: int
