"""`fieldrx worker`: the MQTT telemetry ingest worker (run several; they share the load)."""

from __future__ import annotations

import argparse
import logging
import signal
import threading
from typing import Any


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "worker",
        help="MQTT telemetry ingest worker (MQTT 5 shared subscription)",
        description=(
            "Subscribe to $share/GROUP/fieldrx/machines/+/telemetry, store the batches "
            "(COPY, dedup by machine+seq) and publish TelemetryAck on fieldrx/machines/ID/ack."
        ),
    )
    p.add_argument("--group", default="fieldrx", help="shared subscription group (default fieldrx)")
    p.add_argument("--batch-ms", type=float, default=100.0, help="batching window, ms")
    p.add_argument("--mqtt-url", default=None, help="default: settings MQTT_URL")
    p.add_argument(
        "--client-id",
        default=None,
        help="MQTT client id (default: fieldrx-worker-GROUP-HOST-SLOT, the lowest free slot)",
    )
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fieldrx.fleet.worker import IngestWorker
    from fieldrx.settings import get_settings

    logging.basicConfig(
        level=logging.WARNING if args.quiet else logging.INFO,
        format="%(asctime)s worker %(levelname)s %(message)s",
    )
    s = get_settings()
    worker = IngestWorker(
        args.mqtt_url or s.mqtt_url,
        group=args.group,
        batch_ms=args.batch_ms,
        client_id=args.client_id,
        heartbeat_timeout_s=s.heartbeat_timeout_s,
        session_expiry_s=s.worker_session_expiry_s,
        node=s.worker_node,
        slot_dir=s.worker_slot_dir,
        maintenance_s=s.telemetry_maintenance_s,
        retention_days=s.telemetry_retention_days,
    )
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    stats = worker.run(stop)
    logging.getLogger(__name__).warning("worker stopped: %s", stats)
    return 0
