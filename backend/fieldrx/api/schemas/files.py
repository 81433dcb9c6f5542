"""OpenAPI ``responses=`` entries of routes that answer with bytes, not JSON.

A download declares its media types (zip, CSV, GeoJSON) and a tile its image type, so
the document, the generated client and schemathesis know the body is a file:
``@router.get(..., response_class=Response, responses=file_response("...", "text/csv"))``.
"""

from __future__ import annotations

from typing import Any

_BINARY: dict[str, Any] = {"type": "string", "format": "binary"}
_TEXT: dict[str, Any] = {"type": "string"}
_JSON: dict[str, Any] = {"type": "object"}


def file_response(
    description: str, *media_types: str, status: int = 200
) -> dict[int | str, dict[str, Any]]:
    """``{status: {description, content: {media type: schema}}}``: JSON types (GeoJSON) are
    objects, text types strings, the others binary."""
    content = {
        m: {"schema": _JSON if m.endswith("json") else _TEXT if m.startswith("text/") else _BINARY}
        for m in media_types
    }
    return {status: {"description": description, "content": content}}


MVT = "application/vnd.mapbox-vector-tile"

TILE_RESPONSES: dict[int | str, dict[str, Any]] = {
    **file_response("a Mapbox vector tile, layer 'cells'", MVT),
    304: {"description": "not modified (the ETag of If-None-Match)"},
}
