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
