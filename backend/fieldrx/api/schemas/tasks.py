"""Background tasks (``fieldrx.tasks``): what ``/api/v1/tasks`` answers and the batch body."""

from __future__ import annotations

import datetime as dt
from typing import Any, Literal

from pydantic import Field, model_validator

from fieldrx.api.schemas.base import In, Out
from fieldrx.api.schemas.plans import PlanIn

TaskStatus = Literal["queued", "running", "succeeded", "failed", "cancelled"]
MAX_BATCH = 10_000


class TaskOut(Out):
    """One task: status, progress 0..1 and the stage it is in, the result (and where to
    read it), the error. A batch adds its children's ``counts`` and (on GET) ``items``."""

    id: int
    kind: str
    status: TaskStatus
    progress: float = Field(ge=0, le=1)
    message: str | None
    params: dict[str, Any] | None
    result: dict[str, Any] | None
    result_url: str | None = Field(description="API path of the result (a plan, a prescription)")
    error: str | None
    cancel_requested: bool
    attempts: int
    parent_id: int | None
    created_at: dt.datetime | None
    started_at: dt.datetime | None
    finished_at: dt.datetime | None
    url: str = Field(description="this task's API path (poll it)")
    counts: dict[str, int] | None = None
    items: list[TaskOut] | None = None
    cancelled: int | None = Field(default=None, description="cancel: tasks ended at once")
    stopping: int | None = Field(default=None, description="cancel: running tasks told to stop")


class TaskList(Out):
    items: list[TaskOut]
    total: int
    limit: int
    offset: int


class PlanBatchIn(In):
    """Plan many fields with one set of parameters: ``field_ids`` or every field of
    ``farm_id``."""

    field_ids: list[int] | None = Field(default=None, min_length=1, max_length=MAX_BATCH)
    farm_id: int | None = None
    params: PlanIn = Field(default_factory=PlanIn)

    @model_validator(mode="after")
    def _one_source(self) -> PlanBatchIn:
        if (self.field_ids is None) == (self.farm_id is None):
            raise ValueError("give either field_ids or farm_id")
        return self


QUEUED: dict[int | str, dict[str, Any]] = {
    202: {"model": TaskOut, "description": "queued: poll the task's url"}
}
"""``responses=`` entry of a route that may answer 202 with a task (``?background=true``)."""
