"""Sign-in, organisation switching and API tokens for farm software."""

from __future__ import annotations

import datetime as dt

from fastapi import APIRouter, HTTPException, Request, status
from sqlalchemy import select

from fieldrx.api.schemas.auth import (
    LoginIn,
    LoginOut,
    MeOut,
    NewTokenOut,
    OrgOut,
    SwitchIn,
    TokenIn,
    TokenOut,
    UserOut,
)
from fieldrx.api.schemas.errors import ERRORS, ErrorOut
from fieldrx.auth import throttle
from fieldrx.auth.deps import SessionDep, UserDep
from fieldrx.auth.mqtt import revoke_device_after
from fieldrx.auth.security import verify_password_or_dummy
from fieldrx.auth.service import issue_user_token
from fieldrx.db.models import ROLES, ApiToken, Membership, Organisation, User

router = APIRouter(prefix="/auth", tags=["auth"], responses=ERRORS)


def _orgs(session: SessionDep, user_id: int) -> list[OrgOut]:
    rows = session.execute(
        select(Organisation.id, Organisation.name, Membership.role)
        .join(Membership, Membership.organisation_id == Organisation.id)
        .where(Membership.user_id == user_id)
        .order_by(Organisation.id)
    ).all()
    return [OrgOut(id=r[0], name=r[1], role=r[2]) for r in rows]


def _login(session: SessionDep, user: User, organisation_id: int | None) -> LoginOut:
    orgs = _orgs(session, user.id)
    if not orgs:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "user belongs to no organisation")
    org = (
        orgs[0]
        if organisation_id is None
        else next((o for o in orgs if o.id == organisation_id), None)
    )
    if org is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"organisation {organisation_id} not found")
    token, row = issue_user_token(session, user.id, org.id, org.role)
    expires = row.expires_at
    session.commit()
    return LoginOut(
        access_token=token,
        expires_at=expires,
        user=UserOut(id=user.id, email=user.email, full_name=user.full_name),
        organisation=org,
        organisations=orgs,
    )


@router.post(
    "/login",
    response_model=LoginOut,
    responses={429: {"model": ErrorOut, "description": "too many failed sign-ins (Retry-After)"}},
    openapi_extra={"security": []},  # public: this is where a token comes from
)
def login(body: LoginIn, request: Request, session: SessionDep) -> LoginOut:
    """Exchange e-mail and password for a bearer token scoped to one organisation.

    Failed attempts are throttled per account + client address and per address (429
    with Retry-After, auth.throttle: counted atomically before the password is checked);
    an unknown e-mail costs the same password hashing as a wrong password, so neither the
    answer nor its timing reveals accounts."""
    address = request.client.host if request.client else None
    attempt = throttle.begin(session, body.email, address)
    if attempt.wait_s > 0:
        wait = int(attempt.wait_s) + 1
        raise HTTPException(
            status.HTTP_429_TOO_MANY_REQUESTS,
            f"too many failed sign-ins for this account from this address; try again in {wait} s"
            " (each further failure doubles the wait)",
            headers={"Retry-After": str(wait)},
        )
    user = session.scalar(select(User).where(User.email == body.email.lower()))
    ok = verify_password_or_dummy(body.password, user.password_hash if user else None)
    if user is None or not user.is_active or not ok:
        raise HTTPException(status.HTTP_401_UNAUTHORIZED, "wrong e-mail or password")
    throttle.succeeded(session, body.email, address, attempt)
    return _login(session, user, body.organisation_id)


@router.post("/switch", response_model=LoginOut)
def switch_organisation(body: SwitchIn, principal: UserDep, session: SessionDep) -> LoginOut:
    """New token for another organisation the user belongs to (the organisation switcher)."""
    user = session.get(User, principal.user_id)
    assert user is not None
    return _login(session, user, body.organisation_id)


@router.get("/me", response_model=MeOut)
def me(principal: UserDep, session: SessionDep) -> MeOut:
    user = session.get(User, principal.user_id)
    assert user is not None
    orgs = _orgs(session, user.id)
    current = next(o for o in orgs if o.id == principal.organisation_id)
    return MeOut(
        user=UserOut(id=user.id, email=user.email, full_name=user.full_name),
        organisation=current,
        organisations=orgs,
    )


@router.post("/logout", status_code=204)
def logout(principal: UserDep, session: SessionDep) -> None:
    """Revoke the token used for this request."""
    tok = session.get(ApiToken, principal.token_id)
    assert tok is not None
    tok.revoked_at = dt.datetime.now(dt.UTC)
    session.commit()


@router.get("/tokens", response_model=list[TokenOut])
def list_tokens(principal: UserDep, session: SessionDep) -> list[TokenOut]:
    rows = session.scalars(
        select(ApiToken)
        .where(
            ApiToken.organisation_id == principal.organisation_id,
            ApiToken.user_id == principal.user_id,
        )
        .order_by(ApiToken.id)
    )
    return [TokenOut.model_validate(r, from_attributes=True) for r in rows]


@router.post("/tokens", response_model=NewTokenOut, status_code=201)
def create_token(body: TokenIn, principal: UserDep, session: SessionDep) -> NewTokenOut:
    """A named, expiring API token for farm software; the token is shown only once.

    Without ``role`` the token may write (``agronomist``) when your own role allows it, so a
    developer's first POST works; a viewer's token stays a viewer's."""
    own = principal.role or "viewer"
    role: str = body.role or (
        "agronomist" if ROLES.index(own) <= ROLES.index("agronomist") else own
    )
    if ROLES.index(role) < ROLES.index(own):
        raise HTTPException(
            403,
            f"cannot create a '{role}' token with role '{own}': a token has at most its "
            f"creator's role (ask an admin of your organisation for a '{role}' token)",
        )
    token, row = issue_user_token(
        session,
        principal.user_id or 0,
        principal.organisation_id,
        role,
        name=body.name,
        ttl=dt.timedelta(days=body.expires_in_days),
    )
    session.commit()
    return NewTokenOut(
        token=token, **TokenOut.model_validate(row, from_attributes=True).model_dump()
    )


@router.delete("/tokens/{token_id}", status_code=204)
def revoke_token(token_id: int, principal: UserDep, session: SessionDep) -> None:
    row = session.get(ApiToken, token_id)
    if (
        row is None
        or row.organisation_id != principal.organisation_id
        or (row.user_id != principal.user_id and principal.role != "admin")
    ):
        raise HTTPException(404, f"token {token_id} not found")
    live_device = row.machine_id if row.kind == "device" and row.revoked_at is None else None
    row.revoked_at = dt.datetime.now(dt.UTC)
    session.commit()
    if live_device is not None:  # its MQTT credential goes with it
        revoke_device_after(live_device, f"token {token_id} is revoked")
