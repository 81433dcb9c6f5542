"""Sign-in throttling per account and per address, stored in PostgreSQL (every API process
sees the same counts).

A failed sign-in adds a ``login_failures`` row under ``email:<address>`` and
``ip:<client address>``. When either key has reached its limit within the
window, sign-in is refused with 429 before the password is checked (so a
correct guess cannot be confirmed either). Unknown e-mails are counted like
known ones: the answer never tells which accounts exist. A successful sign-in
clears the account's count.
"""

from __future__ import annotations

import datetime as dt

from sqlalchemy import delete, func, select
from sqlalchemy.orm import Session

from fieldrx.db.models import LoginFailure
from fieldrx.settings import get_settings


def keys(email: str, address: str | None) -> list[str]:
    out = [f"email:{email.strip().lower()[:380]}"]
    if address:
        out.append(f"ip:{address[:380]}")
    return out


def _limit(key: str) -> int:
    s = get_settings()
    return s.login_max_failures_account if key.startswith("email:") else s.login_max_failures_ip


def blocked_for_s(session: Session, email: str, address: str | None) -> float:
    """Seconds until sign-in is allowed again for this account/address (0 when allowed)."""
    window = dt.timedelta(seconds=get_settings().login_window_s)
    now = dt.datetime.now(dt.UTC)
    wait = 0.0
    for key in keys(email, address):
        times = session.scalars(
            select(LoginFailure.at)
            .where(LoginFailure.key == key, LoginFailure.at > now - window)
            .order_by(LoginFailure.at.desc())
            .limit(_limit(key))
        ).all()
        if len(times) >= _limit(key):
            wait = max(wait, (times[-1] + window - now).total_seconds())
    return wait


def record_failure(session: Session, email: str, address: str | None) -> None:
    """Count a failed sign-in (and drop this key's rows older than the window); commits."""
    window = dt.timedelta(seconds=get_settings().login_window_s)
    for key in keys(email, address):
        session.execute(
            delete(LoginFailure).where(
                LoginFailure.key == key, LoginFailure.at <= func.now() - window
            )
        )
        session.add(LoginFailure(key=key))
    session.commit()


def clear_account(session: Session, email: str) -> None:
    session.execute(delete(LoginFailure).where(LoginFailure.key == keys(email, None)[0]))
