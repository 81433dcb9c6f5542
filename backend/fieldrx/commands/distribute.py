"""`fieldrx distribute`: past one node, distribute the machine-keyed tables with Citus.

Run on the Citus coordinator after `fieldrx migrate` (the workers added, PostGIS and
pg_partman created in every node's database). Makes organisations, users, memberships and
api_tokens reference tables and distributes machines by id and every machine-keyed table
by machine_id, co-located with it (``fieldrx.db.citus``). Idempotent: a second run changes
nothing. Refuses, changing nothing, when the citus extension is not in the database or the
schema breaks one of Citus's rules.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict
from typing import Any


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "distribute",
        help="Citus coordinator: make the reference and distributed tables (after migrate)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import psycopg

    from fieldrx.db.citus import NotReady, distribute
    from fieldrx.db.session import raw_dsn

    with psycopg.connect(raw_dsn(), autocommit=True) as conn:
        try:
            rep = distribute(conn)
        except NotReady as exc:
            print(f"fieldrx distribute: {exc}", file=sys.stderr)
            return 2
    print(json.dumps(asdict(rep)))
    if rep.workers == 0:
        print(
            "fieldrx distribute: no worker nodes (citus_add_node): every shard is on the"
            " coordinator",
            file=sys.stderr,
        )
    return 0
