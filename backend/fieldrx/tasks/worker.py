"""A task worker: procrastinate's worker loop plus stalled-job recovery.

procrastinate gives each job to one worker and records every worker's heartbeat
(``FIELDRX_TASK_HEARTBEAT_S``). A worker that dies without stopping (SIGKILL, power loss,
OOM) leaves its jobs in ``doing``; procrastinate does not hand those on by itself. Every
worker therefore runs ``recover_stalled``: each heartbeat interval it asks procrastinate
for the running jobs of workers silent for longer than ``FIELDRX_TASK_STALLED_AFTER_S``
(``JobManager.get_stalled_jobs``, heartbeat based) and puts them back in the queue
(``JobManager.retry_job``). Several workers may race for the same job: the retry of a job
already back in the queue fails in procrastinate and is ignored. A retried task that the
dead worker had in fact finished is not done twice: ``fieldrx.tasks`` (exactly once).

The stalled threshold must exceed the heartbeat interval by a good margin (a busy worker
whose heartbeat is late would otherwise lose its jobs to another worker; the guard still
keeps the result single, but the work would be done twice).

Every worker also deletes task files past their retention (``purge_results``,
``tasks.files``); several doing so at once is harmless (a DELETE by age).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from procrastinate import App, JobContext
from procrastinate.exceptions import JobAborted
from procrastinate.job_context import AbortReason

from fieldrx.errors import Cancelled
from fieldrx.tasks.queue import TASK_NAME, get_app
from fieldrx.tasks.work import execute

log = logging.getLogger(__name__)


def run_task(context: JobContext, task_id: int) -> dict[str, Any] | None:
    """The queue task's code (runs in a worker thread): see ``work.execute``.

    Only a user's abort stops the work; on a worker's shutdown (SIGTERM) running tasks
    finish (they are bounded by their time limit), and a worker killed outright has its
    jobs handed on by stalled-job recovery (below)."""

    def user_abort() -> bool:
        return context.abort_reason() == AbortReason.USER_REQUEST

    try:
        return execute(int(task_id), should_abort=user_abort)
    except Cancelled as exc:
        raise JobAborted(str(exc)) from exc


def worker_app() -> App:
    """The queue's app with the task's code registered (once per process)."""
    app = get_app()
    if TASK_NAME not in app.tasks:
        app.task(name=TASK_NAME, pass_context=True)(run_task)
    return app


async def recover_stalled(app: App, stalled_after_s: float, interval_s: float) -> None:
    """Forever: requeue the running jobs of workers without a heartbeat for
    ``stalled_after_s`` seconds, checking every ``interval_s`` seconds."""
    from procrastinate.exceptions import ConnectorException

    while True:
        await asyncio.sleep(interval_s)
        try:
            stalled = await app.job_manager.get_stalled_jobs(
                seconds_since_heartbeat=stalled_after_s
            )
        except ConnectorException:
            log.warning("stalled-job check failed; retrying", exc_info=True)
            continue
        for job in stalled:
            try:
                await app.job_manager.retry_job(job)
            except ConnectorException:  # another worker requeued it first
                continue
            log.warning(
                "job %s (task %s) of a stalled worker was put back in the queue",
                job.id,
                job.task_kwargs.get("task_id"),
            )


async def purge_results(retention_s: float, interval_s: float) -> None:
    """Forever: delete task files older than ``retention_s``, every ``interval_s`` seconds
    (first right away: a worker that starts after a long stop catches up)."""
    from fieldrx.db.session import get_engine
    from fieldrx.tasks.files import purge_expired

    while True:
        try:
            n = await asyncio.to_thread(purge_expired, get_engine(), retention_s)
            if n:
                log.info("deleted %d task file(s) older than %g s", n, retention_s)
        except Exception:  # a database hiccup: try again next round
            log.warning("purging old task files failed; retrying", exc_info=True)
        await asyncio.sleep(interval_s)


async def expire_device_credentials(check_s: float) -> None:
    """Forever: delete the broker users of machines whose device token expired or was
    revoked behind the API's back (``auth.mqtt.sync_devices``), right after the next
    token's expiry and at least every ``check_s`` seconds, so an expired token stops
    logging in to MQTT at its expiry without a cron job."""
    from fieldrx.auth.mqtt import next_device_expiry_s, sync_devices
    from fieldrx.db.session import get_sessionmaker

    def once() -> float | None:
        with get_sessionmaker()() as session:
            stale = sync_devices(session)
            if stale:
                log.info("deleted the MQTT users of machines %s (token expired or revoked)", stale)
            return next_device_expiry_s(session)

    while True:
        try:
            left = await asyncio.to_thread(once)
        except Exception:  # a broker or database hiccup: try again next round
            log.warning("expiring device MQTT credentials failed; retrying", exc_info=True)
            left = None
        wait = check_s if left is None else min(check_s, left + 0.05)
        await asyncio.sleep(max(0.05, wait))


@dataclass(frozen=True)
class TaskWorkerOptions:
    """How a task worker runs (the FIELDRX_TASK_* settings; seconds)."""

    queues: Iterable[str] | None = None
    concurrency: int = 2
    heartbeat_s: float = 10.0
    stalled_after_s: float = 60.0
    name: str = "fieldrx-tasks"
    result_retention_s: float = 24 * 3600.0
    result_purge_s: float = 600.0
    device_expiry_check_s: float = 60.0


async def run_task_worker(stop: asyncio.Event, opts: TaskWorkerOptions | None = None) -> None:
    """Run jobs until ``stop`` is set; then stop fetching and let running jobs finish.
    First removes what a killed worker or server left (services.cleanup)."""
    o = opts or TaskWorkerOptions()
    queues, concurrency, name = o.queues, o.concurrency, o.name
    heartbeat_s, stalled_after_s = o.heartbeat_s, o.stalled_after_s
    from fieldrx.db.session import get_engine
    from fieldrx.services.cleanup import clean_after_crash_logged

    await asyncio.to_thread(clean_after_crash_logged, get_engine())
    # start the heavy-work forkserver now: its first start imports numpy, shapely, ... for
    # seconds inside the first task's run, where a cancel is not yet watched
    from fieldrx.services.bounded import warm_up

    warm_up()
    app = worker_app()
    async with app.open_async():
        worker = asyncio.create_task(
            app.run_worker_async(
                # None: every queue (procrastinate's Worker takes None; its WorkerOptions
                # TypedDict says Iterable[str] only)
                queues=list(queues) if queues else None,  # type: ignore[arg-type]
                concurrency=concurrency,
                name=name,
                update_heartbeat_interval=heartbeat_s,
                stalled_worker_timeout=stalled_after_s,
                abort_job_polling_interval=min(5.0, heartbeat_s),
                install_signal_handlers=False,
            ),
            name="procrastinate-worker",
        )
        recovery = asyncio.create_task(
            recover_stalled(app, stalled_after_s, heartbeat_s), name="stalled-recovery"
        )
        purge = asyncio.create_task(
            purge_results(o.result_retention_s, o.result_purge_s), name="result-purge"
        )
        expiry = asyncio.create_task(
            expire_device_credentials(o.device_expiry_check_s), name="device-expiry"
        )
        stopping = asyncio.create_task(stop.wait())
        await asyncio.wait({worker, stopping}, return_when=asyncio.FIRST_COMPLETED)
        for side in (recovery, purge, expiry):
            side.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await side
        if not worker.done():
            worker.cancel()  # procrastinate: stop fetching, wait for running jobs
        with contextlib.suppress(asyncio.CancelledError):
            await worker
        stopping.cancel()
