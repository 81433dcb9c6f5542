"""`fieldrx telemetry-maintenance`: premake telemetry's daily partitions, move rows out of
the default partition, drop days past the retention (``fieldrx.fleet.partitions``).

``fieldrx worker`` runs the same every FIELDRX_TELEMETRY_MAINTENANCE_S; a deployment
without MQTT workers runs this from cron (at least twice a day).
"""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict
from typing import Any


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "telemetry-maintenance",
        help="telemetry partitions: premake days, move default-partition rows, retention",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--retention-days",
        type=int,
        default=None,
        help="drop raw records older than this many days, whole days (default: setting"
        " FIELDRX_TELEMETRY_RETENTION_DAYS; 0 keeps everything)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import psycopg

    from fieldrx.db.session import raw_dsn
    from fieldrx.fleet.partitions import maintain
    from fieldrx.settings import get_settings

    days = args.retention_days
    if days is None:
        days = get_settings().telemetry_retention_days
    if days < 0:
        raise SystemExit("--retention-days must be 0 (keep everything) or more")
    with psycopg.connect(raw_dsn(), options="-c jit=off") as conn:
        result = maintain(conn, days)
    print(json.dumps(asdict(result)) if result is not None else "{}")
    return 0
