"""Password hashing and bearer tokens.

Passwords: Argon2id (argon2-cffi). Tokens: 32 random bytes shown once; only an
HMAC-SHA256 digest keyed with the server's secret is stored, so a leaked
database does not leak usable tokens.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets

from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError

from fieldrx.settings import get_settings

_hasher = PasswordHasher()


def hash_password(password: str) -> str:
    return _hasher.hash(password)


_DUMMY_HASH: str | None = None


def verify_password_or_dummy(password: str, password_hash: str | None) -> bool:
    """``verify_password``, or the same Argon2 work against a dummy hash when there is no
    account: an unknown e-mail then answers as slowly as a wrong password (no timing oracle
    for which e-mails exist)."""
    global _DUMMY_HASH
    if password_hash is None:
        if _DUMMY_HASH is None:
            _DUMMY_HASH = _hasher.hash(secrets.token_urlsafe(16))
        verify_password(password, _DUMMY_HASH)
        return False
    return verify_password(password, password_hash)


def verify_password(password: str, password_hash: str) -> bool:
    try:
        return _hasher.verify(password_hash, password)
    except (VerificationError, InvalidHashError):
        return False


def new_token(kind: str) -> str:
    """A fresh token; the prefix tells humans (and secret scanners) what it is."""
    return f"frx_{'d' if kind == 'device' else 'u'}_{secrets.token_urlsafe(32)}"


def token_digest(token: str) -> str:
    key = get_settings().secret_key.encode()
    return hmac.new(key, token.encode(), hashlib.sha256).hexdigest()
