"""The ``import`` task kind: a confirmed ISO 11783-10 TASKDATA import in the background.

``POST /imports/isoxml?confirm=...`` moves the spooled upload into a folder of the
imagery storage's ``.incoming/`` (a place every API process and worker of a deployment
shares, as for imagery uploads) and queues this task with the folder's name. The worker
reads, previews, checks and stores the set in a ``services.bounded`` child (the same
time limit as an inline confirm, ``FIELDRX_PLAN_TIME_LIMIT_S``), in ONE transaction that
also completes the task (``tasks.context.in_transaction``: exactly once), so a failure or a
cancellation stores nothing. The folder is removed once the task has ended either way; a
worker killed mid-way leaves it for the retry (``services.cleanup`` keeps the folders of
open tasks).
"""

from __future__ import annotations

import shutil
from typing import Any

from sqlalchemy.orm import Session

from fieldrx.services.plans import PlanParams
from fieldrx.settings import get_settings
from fieldrx.tasks import store
from fieldrx.tasks.context import Progress, StopFn, TaskInputError, in_transaction, incoming_upload
from fieldrx.tasks.kinds import TASK_KINDS, TaskKind


def _import_work(
    session: Session, params: dict[str, Any], org: int, user: int | None, progress: Progress
) -> tuple[dict[str, Any], str]:
    from fieldrx.services import imports as svc

    folder = incoming_upload(params["incoming"])
    files = [(name, str(folder / stored)) for name, stored in params["files"]]
    if not all((folder / stored).is_file() for _, stored in params["files"]):
        raise TaskInputError("the uploaded TASKDATA is gone (already imported?)")
    req = svc.IsoxmlRequest(
        database_url="",
        files=files,
        source_name=params["source_name"],
        organisation_id=org,
        user_id=user,
        params=PlanParams(**params["plan"]),
        confirm=True,
        density_kg_l=params.get("density_kg_l"),
    )
    out = svc.confirm_isoxml(session, req, progress)
    progress(0.97, "committing")
    c = out["created"]
    result = {"sha256": params["sha256"], "created": c, "skipped": out["preview"]["skipped"]}
    message = (
        f"imported {len(c['fields'])} field(s) ({len(c['matched_fields'])} matched existing), "
        f"{len(c['prescriptions'])} prescription(s)"
    )
    return result, message


def import_child(database_url: str, task_id: int, time_limit_s: float) -> dict[str, Any]:
    """An import task in a ``services.bounded`` child (one transaction)."""
    return in_transaction(database_url, task_id, time_limit_s, _import_work)


def run_import(claimed: store.Claimed, should_stop: StopFn) -> dict[str, Any]:
    from fieldrx.services.bounded import run_bounded

    settings = get_settings()
    limit = settings.plan_time_limit_s
    try:
        return run_bounded(
            import_child,
            settings.database_url,
            claimed.id,
            limit,
            time_limit_s=limit,
            what="the ISOXML import",
            should_stop=should_stop,
        )
    finally:
        shutil.rmtree(incoming_upload(claimed.params["incoming"]), ignore_errors=True)


@TASK_KINDS.register
class ImportKind(TaskKind):
    """A confirmed ISO 11783-10 TASKDATA import (its result names what it created)."""

    name = "import"

    def run(self, claimed: store.Claimed, should_stop: StopFn) -> dict[str, Any]:
        return run_import(claimed, should_stop)
