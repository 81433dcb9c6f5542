"""create_app(): routers, error handlers and the static browser UI."""

from __future__ import annotations

import importlib
from pathlib import Path

import psycopg
from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, JSONResponse
from fastapi.staticfiles import StaticFiles
from sqlalchemy import exc as sa_exc

from fieldrx import __version__
from fieldrx.api.common import ApiError
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
    "jobs",
    "device",
    "telemetry",
    "fleet",
    "reports",
    "live",
)


def _frontend_dist() -> Path:
    configured = get_settings().frontend_dist
    if configured:
        return Path(configured)
    return Path(__file__).resolve().parents[2] / "frontend" / "dist"


def create_app() -> FastAPI:
    app = FastAPI(
        title="FieldRx",
        version=__version__,
        description=(
            "Variable-rate fertilization: fields, coverage planning, path-ordered grids, "
            "prescriptions, ISOXML/Shapefile exports, jobs and fleet telemetry."
        ),
        docs_url="/docs",
        openapi_url=f"{API_PREFIX}/openapi.json",
    )

    @app.exception_handler(ApiError)
    async def _api_error(_: Request, exc: ApiError) -> JSONResponse:
        return JSONResponse(status_code=exc.status_code, content=exc.body)

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
            parts.append(f"{loc}: {err.get('msg')}" if loc else str(err.get("msg")))
        return JSONResponse(
            status_code=422,
            content={
                "detail": "; ".join(parts) or "invalid request",
                "errors": [
                    {"loc": list(e.get("loc", ())), "msg": e.get("msg"), "type": e.get("type")}
                    for e in errors
                ],
            },
        )

    for name in ROUTERS:
        try:
            module = importlib.import_module(f"fieldrx.api.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"fieldrx.api.{name}":
                continue
            raise
        app.include_router(module.router, prefix=API_PREFIX)

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

    return app
