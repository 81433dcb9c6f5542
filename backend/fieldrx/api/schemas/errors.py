"""The one error body of the API and the shared ``responses=`` dict that documents it.

Every 4xx/5xx answer (FastAPI's HTTPException, ``fieldrx.errors`` domain errors, the
API layer's ``ApiError``, request validation, database conflicts) is ``ErrorOut``:
``detail`` is a sentence saying what is wrong and what to change; ``where`` names the
field, row or file when there is one; ``errors`` lists item by item what a validation
or an import refused; other keys carry context (``allowed``, ``flagged``, ...).
"""

from __future__ import annotations

from typing import Any

from pydantic import Field

from fieldrx.api.schemas.base import Open


class ErrorOut(Open):
    """What went wrong and where."""

    detail: str = Field(description="what is wrong and what to do about it")
    where: str | None = Field(
        default=None, description="the field, parameter, row or file the error is about"
    )
    errors: list[dict[str, Any]] | None = Field(
        default=None,
        description="item by item: request validation {loc, msg, type}; imports {row, column, "
        "message}",
    )


def _r(description: str) -> dict[str, Any]:
    return {"model": ErrorOut, "description": description}


ERRORS: dict[int | str, dict[str, Any]] = {
    401: _r("missing, invalid, expired or revoked bearer token"),
    403: _r(
        "the token may not do this (a viewer writing, a device token on a user endpoint); "
        "the message names the role needed"
    ),
    404: _r("no such resource in the caller's organisation"),
    409: _r("conflicts with stored state (a job state transition, evidence that must be kept)"),
    413: _r("request body or upload too large"),
    422: _r("invalid input: the message names the field, row or vertex"),
    503: _r("the database or the worker pool is busy or unreachable: retry (Retry-After)"),
}
"""Pass as ``APIRouter(responses=ERRORS)``: every route documents the error shape."""
