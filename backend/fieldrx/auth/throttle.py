"""Sign-in throttling per account + address and per address, stored in PostgreSQL (every
API process sees the same counts).

Every sign-in attempt is counted before the password is checked: under an advisory lock
per key (held to the end of that short transaction) the failures within the window are
counted and, if no key has reached its limit, the attempt is recorded as a failure at
once. A correct password then deletes that record and clears the account + address count.
So parallel guesses cannot all pass one count (40 at once get at most the limit checked),
and a refused attempt never reaches the password check (a correct guess cannot be
confirmed either).

On top of the limits, the account + address key has a progressive delay: after
``FIELDRX_LOGIN_DELAY_AFTER`` failures in the window, the next attempt is refused (429 with
Retry-After) until ``FIELDRX_LOGIN_DELAY_BASE_S`` x 2^(failures - that) seconds (at most
``MAX_DELAY_S``) have passed since the last failure. The attempt is refused, not held: a
sleeping request would tie up a server thread for the attacker.

Keys: ``acct:<e-mail>|<address>`` (``FIELDRX_LOGIN_MAX_FAILURES``) and ``ip:<address>``
(``FIELDRX_LOGIN_MAX_FAILURES_IP``). The account is throttled per address, so an attacker
who exhausts the account's attempts from one address does not lock the owner out from
another; an attacker spreading guesses over addresses is bounded by the per-address limit
of each. Unknown e-mails are counted like known ones: the answer never tells which
accounts exist.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field

from sqlalchemy import delete, func, insert, select, text
from sqlalchemy.orm import Session

from fieldrx.db.models import LoginFailure
from fieldrx.settings import get_settings

LOCK_NS = 7006  # advisory lock namespace: one login key's count (see module docstring)
MAX_DELAY_S = 60.0  # the progressive delay never grows past this (the limit takes over)


def keys(email: str, address: str | None) -> list[str]:
    out = [f"acct:{email.strip().lower()[:300]}|{(address or '-')[:80]}"]
    if address:
        out.append(f"ip:{address[:380]}")
    return out


def delay_s(failures: int) -> float:
    """The progressive delay after ``failures`` failures of one account + address."""
    s = get_settings()
    over = failures - s.login_delay_after
    if over < 0 or s.login_delay_base_s <= 0:
        return 0.0
    return float(min(MAX_DELAY_S, s.login_delay_base_s * 2.0 ** min(over, 30)))


def _wait_s(key: str, times: list[dt.datetime], now: dt.datetime, window: dt.timedelta) -> float:
    """Seconds this key refuses the next attempt (0: allowed); ``times`` newest first, at
    most the key's limit of them."""
    if len(times) >= _limit(key):
        return max((times[-1] + window - now).total_seconds(), 1.0)
    delay = delay_s(len(times)) if key.startswith("acct:") and times else 0.0
    if delay <= 0:
        return 0.0
    # a parallel attempt may have recorded its failure after ``now`` was read
    return max(0.0, delay - max(0.0, (now - times[0]).total_seconds()))


def _limit(key: str) -> int:
    s = get_settings()
    return s.login_max_failures_account if key.startswith("acct:") else s.login_max_failures_ip


@dataclass
class Attempt:
    """The outcome of ``begin``: ``wait_s`` > 0 refuses the attempt; else ``ids`` are the
    failure rows recorded for it (removed by ``succeeded``)."""

    wait_s: float = 0.0
    ids: list[int] = field(default_factory=list)


def begin(session: Session, email: str, address: str | None) -> Attempt:
    """Count and record one attempt atomically (commits; see module docstring)."""
    window = dt.timedelta(seconds=get_settings().login_window_s)
    now = dt.datetime.now(dt.UTC)
    ks = sorted(keys(email, address))  # one lock order: no deadlock between attempts
    session.rollback()
    wait = 0.0
    for key in ks:
        session.execute(
            text("SELECT pg_advisory_xact_lock(:ns, hashtext(:k))"), {"ns": LOCK_NS, "k": key}
        )
        times = session.scalars(
            select(LoginFailure.at)
            .where(LoginFailure.key == key, LoginFailure.at > now - window)
            .order_by(LoginFailure.at.desc())
            .limit(_limit(key))
        ).all()
        wait = max(wait, _wait_s(key, list(times), now, window))
    if wait > 0:
        session.commit()
        return Attempt(wait_s=wait)
    for key in ks:
        session.execute(
            delete(LoginFailure).where(
                LoginFailure.key == key, LoginFailure.at <= func.now() - window
            )
        )
    ids = session.scalars(
        insert(LoginFailure).returning(LoginFailure.id), [{"key": k} for k in ks]
    ).all()
    session.commit()
    return Attempt(ids=list(ids))


def blocked_for_s(session: Session, email: str, address: str | None) -> float:
    """Seconds until sign-in is allowed again for this account/address (0 when allowed);
    reads only (``begin`` is what a sign-in uses)."""
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
        wait = max(wait, _wait_s(key, list(times), now, window))
    return wait


def record_failure(session: Session, email: str, address: str | None) -> None:
    """Count a failed sign-in outside ``begin`` (commits)."""
    session.execute(insert(LoginFailure), [{"key": k} for k in keys(email, address)])
    session.commit()


def succeeded(session: Session, email: str, address: str | None, attempt: Attempt) -> None:
    """The password was right: the attempt is no failure, and the account's count from
    this address starts again (the caller commits)."""
    session.execute(delete(LoginFailure).where(LoginFailure.id.in_(attempt.ids)))
    session.execute(delete(LoginFailure).where(LoginFailure.key == keys(email, address)[0]))
