"""Who is calling: FastAPI dependencies that resolve a bearer token to a principal.

Every query is scoped by ``principal.organisation_id``; a resource of another
organisation is reported as 404, never 403, so ids do not leak.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, HTTPException, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from fastapi.security.utils import get_authorization_scheme_param
from sqlalchemy import select, update
from sqlalchemy.orm import Session

from fieldrx.auth.security import token_digest
from fieldrx.db.models import ApiToken
from fieldrx.db.session import get_session

WRITE_ROLES = ("admin", "agronomist")

bearer = HTTPBearer(
    scheme_name="bearer",
    bearerFormat="opaque token",
    description="A user token (POST /api/v1/auth/login or /auth/tokens) or a machine's device "
    "token (POST /api/v1/machines/{id}/device-token).",
    auto_error=False,  # our own 401 says what is missing and how to send it
)


@dataclass(frozen=True)
class Principal:
    organisation_id: int
    kind: str  # "user" | "device"
    role: str | None
    user_id: int | None
    machine_id: int | None
    token_id: int

    @property
    def is_device(self) -> bool:
        return self.kind == "device"


def bearer_token(
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)],
) -> str:
    """The token of ``Authorization: Bearer <token>`` (declared as the OpenAPI bearer scheme,
    so /docs shows Authorize); 401 saying how to send it when missing."""
    return token_of(credentials.credentials if credentials is not None else None)


def bearer_token_of(authorization: str | None) -> str:
    """``bearer_token`` for an endpoint that reads the header itself (the device ingest fast
    path, ``fieldrx.api.telemetry``): the same parsing as ``HTTPBearer`` (scheme, a space,
    the token; scheme case-insensitive) and the same 401."""
    scheme, credentials = get_authorization_scheme_param(authorization)
    return token_of(credentials if scheme.lower() == "bearer" else None)


def token_of(credentials: str | None) -> str:
    """The token, stripped; 401 saying how to send it when missing or blank."""
    if credentials is None or not credentials.strip():
        raise HTTPException(
            status.HTTP_401_UNAUTHORIZED,
            "missing bearer token (Authorization: Bearer <token>)",
            headers={"WWW-Authenticate": "Bearer"},
        )
    return credentials.strip()


def resolve_token(session: Session, token: str) -> Principal | None:
    """Look a token up by its digest; None when unknown, revoked or expired."""
    row = session.scalar(select(ApiToken).where(ApiToken.token_hash == token_digest(token)))
    now = dt.datetime.now(dt.UTC)
    if row is None or row.revoked_at is not None:
        return None
    if row.expires_at is not None and row.expires_at <= now:
        return None
    if row.last_used_at is None or (now - row.last_used_at).total_seconds() > 60:
        session.execute(update(ApiToken).where(ApiToken.id == row.id).values(last_used_at=now))
        session.commit()
    return Principal(
        organisation_id=row.organisation_id,
        kind=row.kind,
        role=row.role,
        user_id=row.user_id,
        machine_id=row.machine_id,
        token_id=row.id,
    )


def current_principal(
    token: Annotated[str, Depends(bearer_token)], session: Annotated[Session, Depends(get_session)]
) -> Principal:
    principal = resolve_token(session, token)
    if principal is None:
        raise HTTPException(
            status.HTTP_401_UNAUTHORIZED,
            "invalid, expired or revoked token",
            headers={"WWW-Authenticate": "Bearer"},
        )
    return principal


def current_user(principal: Annotated[Principal, Depends(current_principal)]) -> Principal:
    """A person's token (any role). Device tokens are refused."""
    if principal.is_device:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "device tokens cannot use this endpoint")
    return principal


def writer(principal: Annotated[Principal, Depends(current_user)]) -> Principal:
    """A person allowed to change data (admin or agronomist)."""
    if principal.role not in WRITE_ROLES:
        raise HTTPException(
            status.HTTP_403_FORBIDDEN,
            f"role '{principal.role}' cannot write: this needs role 'agronomist' or 'admin'. "
            "Sign in as such a user, or have one create a token for you with "
            'POST /api/v1/auth/tokens {"name": ..., "role": "agronomist"}',
        )
    return principal


def admin(principal: Annotated[Principal, Depends(current_user)]) -> Principal:
    if principal.role != "admin":
        raise HTTPException(
            status.HTTP_403_FORBIDDEN,
            f"role '{principal.role}' cannot do this: it needs role 'admin' (ask an admin of "
            "your organisation)",
        )
    return principal


def device(principal: Annotated[Principal, Depends(current_principal)]) -> Principal:
    """A machine's device token."""
    if not principal.is_device:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "a device token is required")
    return principal


SessionDep = Annotated[Session, Depends(get_session)]
AnyPrincipal = Annotated[Principal, Depends(current_principal)]
UserDep = Annotated[Principal, Depends(current_user)]
WriterDep = Annotated[Principal, Depends(writer)]
AdminDep = Annotated[Principal, Depends(admin)]
DeviceDep = Annotated[Principal, Depends(device)]
