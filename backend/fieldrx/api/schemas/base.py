"""Base classes of the API's models: strict input, exact output, open stored blobs."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field


class In(BaseModel):
    """A request body: a field the server does not know is refused (422 naming it), not
    silently ignored (a misspelt ``headland_pases`` would otherwise plan with the default)."""

    model_config = ConfigDict(extra="forbid")


class Out(BaseModel):
    """A response body: exactly these fields (``additionalProperties: false`` in OpenAPI)."""

    model_config = ConfigDict(extra="forbid")


class Open(BaseModel):
    """A stored JSON object (summary, metrics, report): known keys typed, others kept."""

    model_config = ConfigDict(extra="allow")


Geometry = dict[str, Any]
"""A GeoJSON geometry object (RFC 7946, lon/lat)."""


class Feature(Out):
    """A GeoJSON Feature whose properties are free-form (cells, track points)."""

    type: Literal["Feature"] = "Feature"
    id: int | None = None
    geometry: Geometry | None
    properties: dict[str, Any]


class Deleted(Out):
    deleted: int = Field(description="rows deleted")
