"""`fieldrx`: serve the API, migrate, load demo data, and the database-free tools (plan, rx).

Subcommands live in ``fieldrx.commands.*``; each module offers
``register(subparsers)`` and is loaded only when present.
"""

from __future__ import annotations

import argparse
import importlib
import sys

COMMAND_MODULES = ("plan", "rx", "worker", "mqtt", "telemetry", "distribute")


def _serve(args: argparse.Namespace) -> int:
    import uvicorn

    from fieldrx.settings import get_settings

    s = get_settings()
    uvicorn.run(
        "fieldrx.app:create_app",
        factory=True,
        host=args.host or s.host,
        port=args.port or s.port,
        workers=args.workers,
        log_level="warning" if args.quiet else "info",
        # SIGTERM: in-flight requests get this long, then heavy workers are stopped
        # (services.bounded) and the server exits
        timeout_graceful_shutdown=10,
    )
    return 0


def _migrate(args: argparse.Namespace) -> int:
    from alembic import command
    from alembic.config import Config

    from fieldrx.db.bootstrap import alembic_config

    cfg: Config = alembic_config()
    command.upgrade(cfg, args.revision)
    if args.revision == "head":  # the kinds the code registers (tasks.kinds), after the schema
        import fieldrx.tasks.work  # noqa: F401  importing it registers every kind
        from fieldrx.db.session import get_engine
        from fieldrx.tasks.kinds import sync_task_kinds

        added = sync_task_kinds(get_engine())
        if added:
            print(f"task kinds added: {', '.join(added)}")
    return 0


def _demo(args: argparse.Namespace) -> int:
    from fieldrx.db.session import get_sessionmaker
    from fieldrx.demo import seed_demo

    with get_sessionmaker()() as session:
        info = seed_demo(session)
    print(f"demo organisation {info.organisation_id}: {info.email} / {info.password}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="fieldrx", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("serve", help="run the API server")
    p.add_argument("--host", default=None)
    p.add_argument("--port", type=int, default=None)
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_serve)

    p = sub.add_parser("migrate", help="apply Alembic migrations")
    p.add_argument("revision", nargs="?", default="head")
    p.set_defaults(func=_migrate)

    p = sub.add_parser("demo", help="load the demo organisation, users, field and machine")
    p.set_defaults(func=_demo)

    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(f"fieldrx.commands.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"fieldrx.commands.{name}":
                continue
            raise
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return int(args.func(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
