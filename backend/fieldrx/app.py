"""create_app(): routers, error handlers, offline API docs and the static browser UI."""

from __future__ import annotations

import importlib
import re
import threading
from pathlib import Path

import psycopg
from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, JSONResponse
from fastapi.staticfiles import StaticFiles
from sqlalchemy import exc as sa_exc
from sqlalchemy.orm import exc as orm_exc

from fieldrx import __version__
from fieldrx.api import telemetry
from fieldrx.apidocs import FIRST_CALL, add_components, install_docs
from fieldrx.auth.mqtt import MqttCredentialError
from fieldrx.errors import DomainError, TooMany
from fieldrx.fleet.gc_policy import tune_for_ingest
from fieldrx.middleware import LimitsAndHeaders, install_log_redaction
from fieldrx.services import bounded
from fieldrx.settings import get_settings

API_PREFIX = "/api/v1"

# Routers in fieldrx.api, mounted when their module exists (resources land one by one).
ROUTERS = (
    "health",
    "auth",
    "farms",
    "fields",
    "machines",
    "plans",
    "tiles",
    "imagery",
    "soil",
    "prescriptions",
    "products",
    "jobs",
    "device",
    "telemetry",
    "fleet",
    "reports",
    "live",
    "archive",
    "imports",
    "tasks",
    "formats",
)


def _frontend_dist() -> Path:
    configured = get_settings().frontend_dist
    if configured:
        return Path(configured)
    return Path(__file__).resolve().parents[2] / "frontend" / "dist"


def _clean_after_crash() -> None:
    """Remove in the background what a killed server or worker left (services.cleanup)."""
    from fieldrx.db.session import get_engine
    from fieldrx.services.cleanup import clean_after_crash_logged

    threading.Thread(
        target=clean_after_crash_logged, args=(get_engine(),), name="crash-cleanup", daemon=True
    ).start()


def create_app() -> FastAPI:
    app = FastAPI(
        title="FieldRx",
        version=__version__,
        description=FIRST_CALL,
        docs_url=None,  # served from the packaged assets by install_docs (no CDN)
        redoc_url=None,
        openapi_url=f"{API_PREFIX}/openapi.json",
    )
    install_docs(app, f"{API_PREFIX}/openapi.json")

    settings = get_settings()
    app.add_middleware(
        LimitsAndHeaders,
        max_body=settings.max_body_bytes,
        max_upload=settings.max_upload_bytes,
        upload_limits=(
            (re.compile(rf"^{API_PREFIX}/fields/\d+/imagery$"), settings.imagery_max_upload_bytes),
        ),
    )
    install_log_redaction()
    bounded.warm_up()
    _clean_after_crash()

    _install_error_handlers(app)
    _install_api(app)
    _install_ui(app)
    tune_for_ingest()  # telemetry bodies: the cyclic GC kept re-walking parsed records
    return app


def _install_error_handlers(app: FastAPI) -> None:
    """Every error the API returns in its one shape (``detail``), with the right status."""

    @app.exception_handler(MqttCredentialError)
    async def _mqtt_error(_: Request, exc: MqttCredentialError) -> JSONResponse:
        """A device credential could not be changed on the broker: nothing was committed."""
        return JSONResponse(status_code=503, content={"detail": str(exc)})

    @app.exception_handler(DomainError)
    async def _domain_error(_: Request, exc: DomainError) -> JSONResponse:
        headers = {"Retry-After": "5"} if exc.status == 503 else None
        if isinstance(exc, TooMany):
            headers = {"Retry-After": str(exc.retry_after_s)}
        return JSONResponse(status_code=exc.status, content=exc.body(), headers=headers)

    @app.exception_handler(sa_exc.OperationalError)
    @app.exception_handler(sa_exc.InterfaceError)
    @app.exception_handler(sa_exc.TimeoutError)
    @app.exception_handler(psycopg.OperationalError)
    async def _db_unavailable(_: Request, exc: Exception) -> JSONResponse:
        """The database is down, restarting or saturated: the client may retry (not a 500)."""
        orig = getattr(exc, "orig", exc)
        reason = str(orig).splitlines()[0] if str(orig) else type(orig).__name__
        return JSONResponse(
            status_code=503,
            content={"detail": f"the database is unavailable; retry shortly ({reason})"},
            headers={"Retry-After": "5"},
        )

    @app.exception_handler(orm_exc.StaleDataError)
    @app.exception_handler(orm_exc.ObjectDeletedError)
    async def _concurrent_change(_: Request, exc: Exception) -> JSONResponse:
        """A row changed or deleted by a concurrent request between read and write."""
        return JSONResponse(
            status_code=409,
            content={"detail": "the resource was changed or deleted by another request; reload"},
        )

    @app.exception_handler(sa_exc.IntegrityError)
    async def _integrity(_: Request, exc: sa_exc.IntegrityError) -> JSONResponse:
        """A write that conflicts with stored rows (a referenced row deleted meanwhile, a
        duplicate): 409, naming the constraint."""
        diag = getattr(exc.orig, "diag", None)
        constraint = getattr(diag, "constraint_name", None) or "a constraint"
        return JSONResponse(
            status_code=409,
            content={"detail": f"conflicts with stored data ({constraint}); reload and retry"},
        )

    @app.exception_handler(sa_exc.DataError)
    @app.exception_handler(psycopg.errors.DataError)
    async def _data_error(_: Request, exc: Exception) -> JSONResponse:
        """Values the database cannot hold (an id beyond 64 bits, a huge offset) are bad input."""
        orig = getattr(exc, "orig", exc)
        reason = str(orig).splitlines()[0] if str(orig) else type(orig).__name__
        return JSONResponse(
            status_code=422, content={"detail": f"a value is out of range: {reason}"}
        )

    @app.exception_handler(RequestValidationError)
    async def _validation_error(_: Request, exc: RequestValidationError) -> JSONResponse:
        errors = exc.errors()
        parts = []
        for err in errors:
            loc = ".".join(str(p) for p in err.get("loc", ()) if p != "body")
            msg = str(err.get("msg"))
            if err.get("type") == "extra_forbidden":  # a misspelt or unsupported field
                msg = "unknown field: not part of this request (see /docs for the fields)"
            parts.append(f"{loc}: {msg}" if loc else msg)
        first = errors[0].get("loc", ()) if errors else ()
        return JSONResponse(
            status_code=422,
            content={
                "detail": "; ".join(parts) or "invalid request",
                "where": ".".join(str(p) for p in first if p != "body") or None,
                "errors": [
                    {"loc": list(e.get("loc", ())), "msg": e.get("msg"), "type": e.get("type")}
                    for e in errors
                ],
            },
        )


def _install_api(app: FastAPI) -> None:
    """The routers under API_PREFIX, the fast device-ingest route and the API's 404."""
    for name in ROUTERS:
        try:
            module = importlib.import_module(f"fieldrx.api.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"fieldrx.api.{name}":
                continue
            raise
        app.include_router(module.router, prefix=API_PREFIX)
    # device ingest, the busiest endpoint: matched first, without FastAPI's per-request
    # dependency solving (fieldrx.api.telemetry: the documented route stays for OpenAPI)
    app.router.routes.insert(0, telemetry.ingest_route(API_PREFIX))
    # the schemas its documented request body refers to (FastAPI registers only the models
    # of bodies it validates, and this route's body must reach it unparsed)
    add_components(app, telemetry.REQUEST_COMPONENTS)

    @app.api_route(
        f"{API_PREFIX}/{{path:path}}",
        methods=["GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"],
        include_in_schema=False,
    )
    def _no_such_endpoint(path: str) -> JSONResponse:
        """No route (a misspelt path, a negative id the ``int`` converter refuses): 404 in the
        one error shape, whatever the method (not the UI's index page, not a bare 405)."""
        return JSONResponse({"detail": f"not found: {API_PREFIX}/{path}"}, status_code=404)


def _install_ui(app: FastAPI) -> None:
    """The built browser UI: its assets, index.html and client-side routes."""
    dist = _frontend_dist()
    index = dist / "index.html"
    if (dist / "assets").is_dir():
        app.mount("/assets", StaticFiles(directory=dist / "assets"), name="assets")

    @app.get("/", include_in_schema=False, response_model=None)
    def _index() -> FileResponse | JSONResponse:
        if index.is_file():
            return FileResponse(index)
        return JSONResponse(
            {"name": "FieldRx", "docs": "/docs", "note": "frontend not built (frontend/dist)"}
        )

    @app.get("/{path:path}", include_in_schema=False, response_model=None)
    def _spa(path: str) -> FileResponse | JSONResponse:
        """Serve built files, and index.html for client-side routes (never for /api)."""
        if path.startswith("api/"):
            return JSONResponse({"detail": f"not found: /{path}"}, status_code=404)
        candidate = (dist / path).resolve()
        if candidate.is_file() and dist.resolve() in candidate.parents:
            return FileResponse(candidate)
        if index.is_file():
            return FileResponse(index)
        return JSONResponse({"detail": f"not found: /{path}"}, status_code=404)
