"""ASGI middleware: request body size limit, security headers, redacted access log.

Pure ASGI (not BaseHTTPMiddleware) so streaming responses and WebSockets pass
through untouched.
"""

from __future__ import annotations

import json
import logging
import re

from starlette.exceptions import HTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from fieldrx.apidocs import DOCS_CSP

# The browser UI: scripts and styles only from the server itself; MapLibre builds its
# workers from blob: URLs and draws tiles of a user-configured https basemap; the live
# view is a WebSocket to the same host.
CSP = "; ".join(
    [
        "default-src 'self'",
        "script-src 'self'",
        "style-src 'self' 'unsafe-inline'",
        "img-src 'self' data: blob: https:",
        "font-src 'self' data:",
        "connect-src 'self' ws: wss: https:",
        "worker-src 'self' blob:",
        "child-src 'self' blob:",
        "object-src 'none'",
        "base-uri 'self'",
        "form-action 'self'",
        "frame-ancestors 'none'",
    ]
)
SECURITY_HEADERS = [
    (b"x-content-type-options", b"nosniff"),
    (b"x-frame-options", b"DENY"),
    (b"referrer-policy", b"no-referrer"),
    (b"cross-origin-opener-policy", b"same-origin"),
    (b"permissions-policy", b"camera=(), microphone=(), geolocation=(self)"),
]
# The API docs pages (served from packaged assets, fieldrx.apidocs) get their own CSP.
_DOCS = ("/docs", "/redoc")


class BodyTooLarge(HTTPException):
    """Raised from ``receive`` when a streamed body passes the limit (FastAPI re-raises
    HTTPExceptions met while reading a body, so the client gets this 413)."""


class LimitsAndHeaders:
    """413 for a body over the limit (``max_upload`` for multipart uploads, ``max_body``
    otherwise) before it is read, by Content-Length, or while it streams in; security
    headers and the CSP on every HTTP response."""

    def __init__(
        self,
        app: ASGIApp,
        max_body: int,
        max_upload: int,
        upload_limits: tuple[tuple[re.Pattern[str], int], ...] = (),
    ) -> None:
        self.app = app
        self.max_body = max_body
        self.max_upload = max_upload
        # routes whose uploads have their own limit (imagery: GeoTIFFs of several GB that the
        # endpoint streams to disk in chunks); first matching path pattern wins
        self.upload_limits = upload_limits

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = dict(scope["headers"])
        multipart = headers.get(b"content-type", b"").lower().startswith(b"multipart/")
        path = scope.get("path", "")
        limit = self.max_upload if multipart else self.max_body
        if multipart:
            limit = next((n for pat, n in self.upload_limits if pat.match(path)), limit)
        started = False

        async def send_with_headers(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
                have = {k.lower() for k, _ in message.get("headers", [])}
                extra = [(k, v) for k, v in SECURITY_HEADERS if k not in have]
                if b"content-security-policy" not in have:
                    csp = DOCS_CSP if path.startswith(_DOCS) else CSP
                    extra.append((b"content-security-policy", csp.encode()))
                message = {**message, "headers": [*message.get("headers", []), *extra]}
            await send(message)

        declared = headers.get(b"content-length", b"")
        if declared.isdigit() and int(declared) > limit:
            await _too_large(send_with_headers, limit)
            return
        received = 0

        async def limited_receive() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    raise BodyTooLarge(413, _too_large_text(limit))
            return message

        try:
            await self.app(scope, limited_receive, send_with_headers)
        except BodyTooLarge:
            if started:
                raise
            await _too_large(send_with_headers, limit)


def _too_large_text(limit: int) -> str:
    return f"request body larger than {limit // (1024 * 1024)} MiB ({limit} bytes); refused"


async def _too_large(send: Send, limit: int) -> None:
    body = json.dumps({"detail": _too_large_text(limit)}).encode()
    await send(
        {
            "type": "http.response.start",
            "status": 413,
            "headers": [
                (b"content-type", b"application/json"),
                (b"content-length", str(len(body)).encode()),
                (b"connection", b"close"),
            ],
        }
    )
    await send({"type": "http.response.body", "body": body})


_SECRET_QUERY = re.compile(r"((?:^|[?&])(?:token|access_token)=)[^&\s\"]*", re.IGNORECASE)


class RedactTokens(logging.Filter):
    """Remove ``token=`` query values from uvicorn's access log lines (a WebSocket URL of an
    older client may still carry its token)."""

    def filter(self, record: logging.LogRecord) -> bool:
        if isinstance(record.args, tuple):
            record.args = tuple(
                _SECRET_QUERY.sub(r"\1[redacted]", a) if isinstance(a, str) else a
                for a in record.args
            )
        if isinstance(record.msg, str):
            record.msg = _SECRET_QUERY.sub(r"\1[redacted]", record.msg)
        return True


def install_log_redaction() -> None:
    for name in ("uvicorn.access", "uvicorn.error", "uvicorn"):
        logger = logging.getLogger(name)
        if not any(isinstance(f, RedactTokens) for f in logger.filters):
            logger.addFilter(RedactTokens())
