"""The procrastinate app and FieldRx's one queue task.

Every kind of work goes through one procrastinate task, ``fieldrx.run_task(task_id)``,
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

from procrastinate import App, JobContext, PsycopgConnector
from procrastinate.exceptions import JobAborted
from procrastinate.job_context import AbortReason

from fieldrx.db.session import raw_dsn
from fieldrx.settings import get_settings

TASK_NAME = "fieldrx.run_task"


def _run_task(context: JobContext, task_id: int) -> dict[str, Any] | None:
    """The queue's entry point (runs in a worker thread): see ``work.execute``.

    Only a user's abort stops the work; on a worker's shutdown (SIGTERM) running tasks
    finish (they are bounded by their time limit), and a worker killed outright has its
    jobs handed on by stalled-job recovery (``tasks.worker``)."""
    from fieldrx.errors import Cancelled
    from fieldrx.tasks.work import execute

    def user_abort() -> bool:
        return context.abort_reason() == AbortReason.USER_REQUEST

    try:
        return execute(int(task_id), should_abort=user_abort)
    except Cancelled as exc:
        raise JobAborted(str(exc)) from exc


@lru_cache
def get_app() -> App:
    """The procrastinate app on the configured database (pool opened only by workers)."""
    connector = PsycopgConnector(
        conninfo=raw_dsn(get_settings().database_url),
        kwargs={"options": "-c jit=off"},
        min_size=1,
        max_size=4,
    )
    app = App(connector=connector)
    app.task(name=TASK_NAME, pass_context=True)(_run_task)
    return app


def make_jobs(kinds_and_ids: list[tuple[str, int]]) -> list[Any]:
    """procrastinate jobs (not yet deferred) for task rows: queue = kind."""
    task = get_app().tasks[TASK_NAME]
    return [task.configure(queue=kind).make_new_job(task_id=tid) for kind, tid in kinds_and_ids]
