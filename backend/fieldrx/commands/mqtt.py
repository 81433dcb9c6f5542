"""`fieldrx mqtt-init`: the broker's dynamic-security file with the FieldRx service users."""

from __future__ import annotations

import argparse
import sys
from typing import Any


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "mqtt-init",
        help="create the broker's dynamic-security file (service users and roles)",
        description=(
            "Write a new Mosquitto dynamic-security file holding the fieldrx-admin and "
            "fieldrx-worker users (passwords derived from SECRET_KEY) and their roles; an "
            "existing file is left alone. With --check, log in to MQTT_URL as both users."
        ),
    )
    p.add_argument("--file", help="dynamic-security JSON to create (before the broker starts)")
    p.add_argument("--check", action="store_true", help="verify both service logins on MQTT_URL")
    p.set_defaults(func=run)
    p = subparsers.add_parser(
        "mqtt-sync",
        help="delete broker users of machines without a live device token (run periodically)",
    )
    p.set_defaults(func=run_sync)


def run(args: argparse.Namespace) -> int:
    from fieldrx.auth.mqtt import WORKER_USER, Broker, DynsecAdmin, bootstrap, login_error
    from fieldrx.settings import get_settings

    if args.file:
        created = bootstrap(args.file)
        print(f"{args.file}: {'created' if created else 'exists, left alone'}")
    if args.check:
        url = get_settings().mqtt_url
        errors = [
            e
            for e in (
                login_error(DynsecAdmin(url).broker),
                login_error(Broker.from_url(url, WORKER_USER)),
            )
            if e
        ]
        if errors:
            print(
                "\n".join(errors) + "\n(the service passwords derive from SECRET_KEY as it was"
                " when the dynamic-security file was created: use that SECRET_KEY, or"
                " recreate the file)",
                file=sys.stderr,
            )
            return 1
        print("MQTT service users OK")
    return 0


def run_sync(args: argparse.Namespace) -> int:
    from fieldrx.auth.mqtt import MqttCredentialError, sync_devices
    from fieldrx.db.session import get_sessionmaker

    try:
        with get_sessionmaker()() as session:
            stale = sync_devices(session)
    except MqttCredentialError as exc:
        print(exc, file=sys.stderr)
        return 1
    print(f"deleted MQTT users of machines {stale}" if stale else "MQTT users in step")
    return 0
