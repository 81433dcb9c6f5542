"""Creating organisations, users, memberships and tokens (used by the API, demo data and tests)."""

from __future__ import annotations

import datetime as dt

from sqlalchemy import select
from sqlalchemy.orm import Session

from fieldrx.auth.mqtt import provision_device
from fieldrx.auth.security import hash_password, new_token, token_digest
from fieldrx.db.models import ROLES, ApiToken, Membership, Organisation, User
from fieldrx.settings import get_settings


def create_organisation(session: Session, name: str) -> Organisation:
    org = Organisation(name=name)
    session.add(org)
    session.flush()
    return org


def create_user(session: Session, email: str, password: str, full_name: str = "") -> User:
    user = User(email=email.lower(), password_hash=hash_password(password), full_name=full_name)
    session.add(user)
    session.flush()
    return user


def add_membership(session: Session, user: User, org: Organisation, role: str) -> Membership:
    if role not in ROLES:
        raise ValueError(f"unknown role {role!r}; expected one of {ROLES}")
    m = Membership(user_id=user.id, organisation_id=org.id, role=role)
    session.add(m)
    session.flush()
    return m


def issue_user_token(
    session: Session,
    user_id: int,
    organisation_id: int,
    role: str,
    name: str = "login",
    ttl: dt.timedelta | None = None,
) -> tuple[str, ApiToken]:
    """A new user token and its row; the token text exists only in the return value."""
    token = new_token("user")
    ttl = ttl if ttl is not None else dt.timedelta(hours=get_settings().token_ttl_hours)
    row = ApiToken(
        organisation_id=organisation_id,
        kind="user",
        user_id=user_id,
        role=role,
        name=name,
        token_hash=token_digest(token),
        prefix=token[:12],
        expires_at=dt.datetime.now(dt.UTC) + ttl,
    )
    session.add(row)
    session.flush()
    return token, row


def token_expiry(session: Session, token: str) -> dt.datetime | None:
    """When a token (given as its text) expires."""
    return session.scalar(
        select(ApiToken.expires_at).where(ApiToken.token_hash == token_digest(token))
    )


def issue_device_token(session: Session, machine_id: int, organisation_id: int) -> str:
    """A machine's token; issuing a new one revokes the previous ones.

    It expires after ``FIELDRX_DEVICE_TOKEN_TTL_DAYS`` (a token copied off a tractor
    does not work forever); the machine rotates it before then with
    ``POST /device/token`` (api/device.py)."""
    now = dt.datetime.now(dt.UTC)
    for old in session.scalars(
        select(ApiToken).where(
            ApiToken.machine_id == machine_id,
            ApiToken.kind == "device",
            ApiToken.revoked_at.is_(None),
        )
    ):
        old.revoked_at = now
    token = new_token("device")
    session.add(
        ApiToken(
            organisation_id=organisation_id,
            kind="device",
            machine_id=machine_id,
            name=f"machine {machine_id}",
            token_hash=token_digest(token),
            prefix=token[:12],
            expires_at=now + dt.timedelta(days=get_settings().device_token_ttl_days),
        )
    )
    session.flush()
    # the broker credential follows the token (raises MqttCredentialError: nothing committed)
    provision_device(machine_id, token)
    return token
