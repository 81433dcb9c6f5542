"""The procrastinate app and FieldRx's one queue task.

Every kind of work goes through one procrastinate task, ``fieldrx.run_task(task_id)``
(its code: ``tasks.worker.run_task``),
on a queue named after the kind (``plan``, ``prescription``, ``imagery``), so a worker
can be limited to some kinds (``fieldrx worker --queues imagery``). The task's inputs
are in its ``tasks`` row, not in the job's arguments: the row is what the API shows and
what the work's transaction checks (``fieldrx.tasks`` docstring: exactly once).

The API process never opens the app's connection pool: it defers jobs on the request's
own connection (``store.create_tasks``), in the transaction that inserts the task rows,
so a task row never exists without its job or the other way round.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

from procrastinate import App, PsycopgConnector

from fieldrx.db.session import raw_dsn
from fieldrx.settings import get_settings

TASK_NAME = "fieldrx.run_task"


@lru_cache
def get_app() -> App:
    """The procrastinate app on the configured database (pool opened only by workers)."""
    connector = PsycopgConnector(
        conninfo=raw_dsn(get_settings().database_url),
        kwargs={"options": "-c jit=off"},
        min_size=1,
        max_size=4,
    )
    # the task's code is registered by the worker (``tasks.worker``); the API only defers
    # jobs by the task's name, so this module needs none of the work's modules
    return App(connector=connector)


def make_jobs(kinds_and_ids: list[tuple[str, int]]) -> list[Any]:
    """procrastinate jobs (not yet deferred) for task rows: queue = kind."""
    app = get_app()
    return [
        app.configure_task(name=TASK_NAME, queue=kind).make_new_job(task_id=tid)
        for kind, tid in kinds_and_ids
    ]
