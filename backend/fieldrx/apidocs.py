"""API documentation served by the app itself: Swagger UI at /docs, ReDoc at /redoc.

Both pages load their scripts and styles from the ``fastapi-offline`` package's copy
(mounted at ``/docs-assets``), never from a CDN: a tractor-side laptop or a farm office
without internet still gets working docs, and no request leaves the server's host.
``FIRST_CALL`` is the short guide in the OpenAPI description (and docs/api.md).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from fastapi import FastAPI
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles
from pydantic import TypeAdapter
from pydantic.json_schema import GenerateJsonSchema

ASSETS_URL = "/docs-assets"

FIRST_CALL = """
Variable-rate fertilization: fields, coverage planning, path-ordered grids, prescriptions,
ISOXML/Shapefile exports, jobs and fleet telemetry.

## First call

Every request carries `Authorization: Bearer <token>` (the **Authorize** button above).

1. **A token that may write.** Sign in, then make a named token for your software; without
   `role` it is an `agronomist` token (may write) when your own role allows it:

       curl -s -X POST $URL/api/v1/auth/login -H 'Content-Type: application/json' \\
         -d '{"email": "agronomist@demo.fieldrx.org", "password": "fieldrx-demo"}'
       curl -s -X POST $URL/api/v1/auth/tokens -H "Authorization: Bearer $LOGIN_TOKEN" \\
         -H 'Content-Type: application/json' -d '{"name": "my script"}'

   A `viewer` token only reads: a write answers 403 naming the role it needs.
2. **A field**: `POST /api/v1/fields` with a GeoJSON Feature (Polygon, lon/lat):
   `{"type": "Feature", "geometry": {...}, "properties": {"name": "North"}}`.
3. **A plan**: `POST /api/v1/fields/{field_id}/plans` `{"swath_width_m": 12, "cell_length_m": 10}`.
4. **Soil samples** (for a nutrient-balance prescription):
   `POST /api/v1/fields/{field_id}/soil-samples` with a CSV file (`lon,lat,n_mg_kg`).
5. **A prescription**: `POST /api/v1/plans/{plan_id}/prescriptions`
   `{"model": "uniform", "params": {"rate_kg_ha": 150}}` (or `nutrient_balance` with
   `"interpolation": "idw"`; `model` lists every rate model, `params` their parameters).
6. **ISOXML for the terminal**:
   `GET /api/v1/prescriptions/{rx_id}/export?format=isoxml` answers `TASKDATA.zip`.

Errors are one shape (`ErrorOut`): `detail` says what is wrong and what to change, `where`
names the field. Unknown body fields are refused (422), not ignored.
"""

# The docs pages run FastAPI's small inline start-up script; everything else is ours.
DOCS_CSP = "; ".join(
    [
        "default-src 'self'",
        "script-src 'self' 'unsafe-inline'",
        "style-src 'self' 'unsafe-inline'",
        "img-src 'self' data: blob:",
        "font-src 'self' data:",
        "connect-src 'self'",
        "worker-src 'self' blob:",
        "object-src 'none'",
        "base-uri 'self'",
        "frame-ancestors 'none'",
    ]
)


def assets_dir() -> Path:
    """The packaged Swagger UI / ReDoc files (``fastapi_offline/static``)."""
    import fastapi_offline

    return Path(fastapi_offline.__file__).resolve().parent / "static"


def install_docs(app: FastAPI, openapi_url: str) -> None:
    """Mount the assets and the two pages (create the app with docs_url=redoc_url=None)."""
    app.mount(ASSETS_URL, StaticFiles(directory=assets_dir()), name="docs-assets")
    title = app.title

    @app.get("/docs", include_in_schema=False)
    def swagger_ui() -> HTMLResponse:
        return get_swagger_ui_html(
            openapi_url=openapi_url,
            title=f"{title} API",
            swagger_js_url=f"{ASSETS_URL}/swagger-ui-bundle.js",
            swagger_css_url=f"{ASSETS_URL}/swagger-ui.css",
            swagger_favicon_url=f"{ASSETS_URL}/favicon.png",
            # no badge fetched from the public validator service
            swagger_ui_parameters={"validatorUrl": None, "persistAuthorization": True},
        )

    @app.get("/redoc", include_in_schema=False)
    def redoc() -> HTMLResponse:
        return get_redoc_html(
            openapi_url=openapi_url,
            title=f"{title} API",
            redoc_js_url=f"{ASSETS_URL}/redoc.standalone.js",
            redoc_favicon_url=f"{ASSETS_URL}/favicon.png",
            with_google_fonts=False,
        )


COMPONENT_REF = "#/components/schemas/{model}"


def schema_and_components(
    tp: Any, generator: type[GenerateJsonSchema] = GenerateJsonSchema
) -> tuple[dict[str, Any], dict[str, Any]]:
    """The JSON schema of ``tp`` (a model, a union of models) for a route's ``openapi_extra``,
    its references pointing into ``components/schemas``, and the schemas they name (for
    ``add_components``). For a request body FastAPI must not parse (a route that reads the
    body itself and answers its own way): FastAPI registers the models only of the bodies
    it validates and of responses, and pydantic's own ``$defs`` left inside an operation
    would be references to nowhere."""
    schema = TypeAdapter(tp).json_schema(ref_template=COMPONENT_REF, schema_generator=generator)
    return schema, schema.pop("$defs", {})


def add_components(app: FastAPI, schemas: Mapping[str, dict[str, Any]]) -> None:
    """Put ``schemas`` (``schema_and_components``) into ``app``'s OpenAPI document, by name,
    next to the models FastAPI registers itself (kept sorted as FastAPI sorts them). A name
    FastAPI already uses for another schema is an error, not a silent overwrite."""
    generate = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is not None:  # FastAPI's cache: the schemas are in
            return app.openapi_schema
        doc = generate()
        components = doc.setdefault("components", {})
        have = components.setdefault("schemas", {})
        for name, schema in schemas.items():
            if have.setdefault(name, schema) != schema:
                app.openapi_schema = None  # not cached half made
                raise ValueError(f"two OpenAPI component schemas named {name!r}")
        components["schemas"] = dict(sorted(have.items()))
        return doc

    app.openapi = openapi  # type: ignore[method-assign]


def openapi_json(app: FastAPI) -> str:
    """``app``'s OpenAPI document as committed in ``frontend/src/api/openapi.json`` (the
    generated TypeScript client's source; ``tests/system/test_contract.py`` fails when it is
    stale)."""
    import json

    return json.dumps(app.openapi(), indent=2, ensure_ascii=False) + "\n"


def schema_defaults_json(document: str) -> str:
    """``{model: {field: default}}`` of every model field with a scalar default in the OpenAPI
    ``document``, as committed in ``frontend/src/api/generated/defaults.json``.

    The browser's forms start from these values instead of keeping copies (a copy drifted:
    the plan form said 1 headland pass where the API said 0, the prescription form ``idw``
    where the API said ``cell_mean``). The server's model is the one home of a default; the
    OpenAPI document carries it, and this file carries it into the bundle without the
    document's ~0.5 MB. ``tests/system/test_contract.py`` fails when the file is stale.
    """
    import json

    schemas = json.loads(document).get("components", {}).get("schemas", {})
    out: dict[str, dict[str, object]] = {}
    for name in sorted(schemas):
        props = schemas[name].get("properties") or {}
        d: dict[str, object] = {
            k: p["default"]
            for k, p in sorted(props.items())
            if "default" in p
            and (p["default"] is None or isinstance(p["default"], str | int | float | bool))
        }
        if d:
            out[name] = d
    return json.dumps(out, indent=2, ensure_ascii=False) + "\n"
