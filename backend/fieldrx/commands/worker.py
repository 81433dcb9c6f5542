"""`fieldrx worker`: the background worker. Two roles, both by default:

- ``ingest``: the MQTT telemetry ingest worker (MQTT 5 shared subscription; run several,
  they share the load), ``fleet.worker``;
- ``tasks``: runs background tasks from the PostgreSQL queue (plans, prescriptions,
  imagery ingest, exports, job reports; run several on any hosts, they share the queue),
  ``fieldrx.tasks``.

``--role tasks`` or ``--role ingest`` runs one of them (e.g. to scale them separately).
SIGTERM/SIGINT stop both: ingest acknowledges what it stored, the task worker stops
fetching and lets running tasks finish.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import signal
import threading
from typing import Any


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "worker",
        help="background worker: MQTT telemetry ingest and/or background tasks",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--role",
        choices=("all", "ingest", "tasks"),
        default="all",
        help="which work to do (default all: ingest and tasks)",
    )
    g = p.add_argument_group("ingest role")
    g.add_argument("--group", default="fieldrx", help="shared subscription group (default fieldrx)")
    g.add_argument("--batch-ms", type=float, default=100.0, help="batching window, ms")
    g.add_argument("--mqtt-url", default=None, help="default: settings MQTT_URL")
    g.add_argument(
        "--db-connections",
        type=int,
        default=None,
        help="database connections (lanes) per ingest worker (default"
        " FIELDRX_WORKER_DB_CONNECTIONS, 1)",
    )
    g.add_argument(
        "--client-id",
        default=None,
        help="MQTT client id (default: fieldrx-worker-GROUP-HOST-SLOT, the lowest free slot)",
    )
    t = p.add_argument_group("tasks role")
    t.add_argument(
        "--queues",
        default="",
        help="comma-separated queues to serve (default all: one per task kind, tasks.kinds)",
    )
    t.add_argument(
        "--concurrency",
        type=int,
        default=None,
        help="tasks run at once (default FIELDRX_TASK_CONCURRENCY)",
    )
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=run)


def _run_ingest(args: argparse.Namespace, stop: threading.Event) -> None:
    from fieldrx.fleet.gc_policy import tune_for_ingest
    from fieldrx.fleet.worker import IngestOptions, IngestWorker
    from fieldrx.settings import get_settings

    s = get_settings()
    tune_for_ingest()  # held batches made the cyclic GC a third of the parse cost
    opts = IngestOptions(
        group=args.group,
        batch_ms=args.batch_ms,
        client_id=args.client_id,
        heartbeat_timeout_s=s.heartbeat_timeout_s,
        session_expiry_s=s.worker_session_expiry_s,
        node=s.worker_node,
        slot_dir=s.worker_slot_dir,
        maintenance_s=s.telemetry_maintenance_s,
        retention_days=s.telemetry_retention_days,
        db_connections=args.db_connections or s.worker_db_connections,
    )
    worker = IngestWorker(args.mqtt_url or s.mqtt_url, opts=opts)
    stats = worker.run(stop)
    logging.getLogger(__name__).warning("ingest worker stopped: %s", stats)


async def _main(args: argparse.Namespace) -> None:
    from fieldrx.settings import get_settings
    from fieldrx.tasks.kinds import queues as task_queues
    from fieldrx.tasks.worker import TaskWorkerOptions, run_task_worker

    s = get_settings()
    stop = asyncio.Event()
    stop_thread = threading.Event()

    def on_signal() -> None:
        stop.set()
        stop_thread.set()

    loop = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, on_signal)
    roles: list[asyncio.Task[None]] = []
    if args.role in ("all", "ingest"):
        roles.append(asyncio.create_task(asyncio.to_thread(_run_ingest, args, stop_thread)))
    if args.role in ("all", "tasks"):
        queues = [q.strip() for q in args.queues.split(",") if q.strip()]
        known = task_queues()
        unknown = sorted(set(queues) - set(known))
        if unknown:
            raise SystemExit(f"unknown queue(s) {unknown}; the queues are {list(known)}")
        roles.append(
            asyncio.create_task(
                run_task_worker(
                    stop,
                    TaskWorkerOptions(
                        queues=queues or None,
                        concurrency=args.concurrency or s.task_concurrency,
                        heartbeat_s=s.task_heartbeat_s,
                        stalled_after_s=s.task_stalled_after_s,
                        result_retention_s=s.task_result_retention_s,
                        result_purge_s=s.task_result_purge_s,
                        device_expiry_check_s=s.device_expiry_check_s,
                    ),
                )
            )
        )
    try:
        # one role ending (or failing) stops the other
        done, _ = await asyncio.wait(roles, return_when=asyncio.FIRST_COMPLETED)
    finally:
        on_signal()
    await asyncio.gather(*roles, return_exceptions=True)
    for task in done:
        task.result()


def run(args: argparse.Namespace) -> int:
    logging.basicConfig(
        level=logging.WARNING if args.quiet else logging.INFO,
        format="%(asctime)s worker %(levelname)s %(message)s",
    )
    asyncio.run(_main(args))
    return 0
