"""Sign-in, organisations and API tokens."""

from __future__ import annotations

import datetime as dt
from typing import Literal

from pydantic import Field

from fieldrx.api.schemas.base import In, Out

Role = Literal["admin", "agronomist", "viewer"]


class LoginIn(In):
    email: str = Field(max_length=320)
    password: str = Field(max_length=1000)
    organisation_id: int | None = Field(
        default=None, description="organisation to sign in to (default: the first one)"
    )


class SwitchIn(In):
    organisation_id: int


class OrgOut(Out):
    id: int
    name: str
    role: str


class UserOut(Out):
    id: int
    email: str
    full_name: str


class MeOut(Out):
    user: UserOut
    organisation: OrgOut
    organisations: list[OrgOut]


class LoginOut(MeOut):
    access_token: str
    token_type: Literal["bearer"] = "bearer"
    expires_at: dt.datetime | None


class TokenIn(In):
    name: str = Field(min_length=1, max_length=200)
    role: Role | None = Field(
        default=None,
        description="the token's role, at most your own. Default: 'agronomist' (may write) "
        "when your role allows it, else your own role ('viewer' tokens only read)",
    )
    expires_in_days: float = Field(default=90, gt=0, le=3650)


class TokenOut(Out):
    id: int
    name: str
    role: str | None
    prefix: str
    created_at: dt.datetime
    expires_at: dt.datetime | None
    revoked_at: dt.datetime | None


class NewTokenOut(TokenOut):
    token: str = Field(description="the secret: shown only once")
