"""MQTT credentials: the broker's users, their topics, device credentials bound to device tokens.

The broker (Mosquitto 2 with its dynamic-security plugin, ``deploy/mosquitto*.conf``)
admits no anonymous client. Three kinds of user exist:

* ``fieldrx-admin`` - the API server. Its only right is the plugin's control topic,
  through which it creates and deletes device users (:class:`DynsecAdmin`).
* ``fieldrx-worker`` - every ingest worker: reads every machine's telemetry, writes acks.
* ``machine-<id>`` (:func:`fieldrx_edge.protocol.mqtt_username`) - one per machine. Its
  password is the machine's *current device token*: the device already holds it, and the
  broker keeps only a salted PBKDF2-SHA512 hash of it. The user is (re)created when a
  device token is issued and deleted when the token is revoked, so a revoked or replaced
  token stops working on the broker too (the broker also disconnects a deleted user's
  live connection). It must connect with client id ``fieldrx-edge-<id>`` (a device
  reusing a worker's client id would otherwise take over and disconnect its session).
  Its role allows publishing ``fieldrx/machines/<id>/telemetry`` and reading
  ``.../<id>/ack`` and ``.../<id>/jobs``, nothing else: no other machine's topics,
  no ``#``, and no acks (only workers publish acks).

The two service passwords are derived from ``SECRET_KEY`` (HMAC-SHA256), so a
deployment has one secret to manage; :func:`bootstrap` writes them into a new
dynamic-security file before the broker first starts.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import json
import os
import pwd
import secrets
import threading
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlparse

import paho.mqtt.client as mqtt
from fieldrx_edge.protocol import (
    ack_topic,
    jobs_topic,
    mqtt_client_id,
    mqtt_username,
    telemetry_topic,
)
from sqlalchemy import func, or_, select
from sqlalchemy.orm import Session

from fieldrx.db.models import ApiToken
from fieldrx.settings import get_settings

ADMIN_USER = "fieldrx-admin"
WORKER_USER = "fieldrx-worker"
ADMIN_ROLE = "fieldrx-admin"
WORKER_ROLE = "fieldrx-worker"
CONTROL_TOPIC = "$CONTROL/dynamic-security/v1"
# every machine's telemetry, as the worker subscribes to it (plain or $share/GROUP/...)
ALL_TELEMETRY = telemetry_topic(0).replace("/0/", "/+/")
ALL_ACKS = ack_topic(0).replace("/0/", "/+/")


class MqttCredentialError(RuntimeError):
    """The broker could not be reached or refused a credential change."""


def service_password(username: str) -> str:
    """Password of a FieldRx service user: HMAC-SHA256(SECRET_KEY, "mqtt:" + username)."""
    key = get_settings().secret_key.encode()
    return hmac.new(key, f"mqtt:{username}".encode(), hashlib.sha256).hexdigest()


@dataclass(frozen=True)
class Broker:
    """Where and as whom to connect: ``mqtt[s]://[user[:password]@]host[:port]``.

    Without user-info the given service user and its derived password are used;
    ``mqtts://`` turns on TLS (CA bundle: MQTT_CA_FILE, else the system's).
    """

    host: str
    port: int
    username: str
    password: str
    tls: bool

    @classmethod
    def from_url(cls, url: str, default_user: str) -> Broker:
        u = urlparse(url)
        if u.scheme not in ("mqtt", "mqtts"):
            raise ValueError(f"MQTT URL {url!r}: scheme must be mqtt:// or mqtts://")
        tls = u.scheme == "mqtts"
        user = unquote(u.username) if u.username else default_user
        password = unquote(u.password) if u.password else service_password(user)
        port = u.port or (8883 if tls else 1883)
        return cls(u.hostname or "127.0.0.1", port, user, password, tls)

    def configure(self, client: mqtt.Client) -> None:
        """Set the credentials (and TLS) on a paho client before it connects."""
        client.username_pw_set(self.username, self.password)
        if self.tls:
            client.tls_set(ca_certs=get_settings().mqtt_ca_file or None)


def login_error(broker: Broker, timeout_s: float = 5.0) -> str | None:
    """Why ``broker``'s user cannot log in (None if it can)."""
    got: list[mqtt.ReasonCode] = []
    done = threading.Event()
    client = mqtt.Client(
        mqtt.CallbackAPIVersion.VERSION2,
        client_id=f"fieldrx-check-{uuid.uuid4().hex[:12]}",
        protocol=mqtt.MQTTv5,
    )
    broker.configure(client)
    def on_connect(
        c: mqtt.Client, u: Any, f: Any, rc: mqtt.ReasonCode, p: Any
    ) -> None:
        got.append(rc)
        done.set()

    client.on_connect = on_connect
    try:
        client.connect(broker.host, broker.port, keepalive=10)
    except OSError as exc:
        return f"MQTT broker {broker.host}:{broker.port} unreachable: {exc}"
    client.loop_start()
    try:
        if not done.wait(timeout_s):
            return f"MQTT broker {broker.host}:{broker.port}: no CONNACK"
        if got[0].is_failure:
            return f"MQTT broker {broker.host}:{broker.port} refused {broker.username}: {got[0]}"
        return None
    finally:
        client.disconnect()
        client.loop_stop()


# -- roles ---------------------------------------------------------------------------


def _acl(acltype: str, topic: str) -> dict[str, Any]:
    return {"acltype": acltype, "topic": topic, "priority": 0, "allow": True}


def device_role(machine_id: int) -> dict[str, Any]:
    """The one machine's rights: publish its telemetry, read its acks and jobs."""
    acls = [_acl("publishClientSend", telemetry_topic(machine_id))]
    for topic in (ack_topic(machine_id), jobs_topic(machine_id)):
        acls += [_acl("subscribeLiteral", topic), _acl("publishClientReceive", topic)]
    return {"rolename": mqtt_username(machine_id), "acls": acls}


def service_roles() -> list[dict[str, Any]]:
    control = "$CONTROL/dynamic-security/#"
    return [
        {
            "rolename": ADMIN_ROLE,
            "acls": [
                _acl("publishClientSend", control),
                _acl("subscribePattern", control),
                _acl("publishClientReceive", control),
            ],
        },
        {
            "rolename": WORKER_ROLE,
            "acls": [
                _acl("subscribePattern", ALL_TELEMETRY),
                # Mosquitto 2.0 checks a shared subscription with its $share/GROUP/ prefix
                _acl("subscribePattern", "$share/+/" + ALL_TELEMETRY),
                _acl("publishClientReceive", ALL_TELEMETRY),
                _acl("publishClientSend", ALL_ACKS),
            ],
        },
    ]


def _hashed(password: str, iterations: int = 101) -> dict[str, Any]:
    """The plugin's stored form: base64 PBKDF2-HMAC-SHA512 over the base64-decoded salt
    (101 iterations is the plugin's own default; the passwords are 256-bit random)."""
    salt = secrets.token_bytes(12)
    digest = hashlib.pbkdf2_hmac("sha512", password.encode(), salt, iterations)
    return {
        "password": base64.b64encode(digest).decode(),
        "salt": base64.b64encode(salt).decode(),
        "iterations": iterations,
    }


def bootstrap(path: str | Path) -> bool:
    """Write a new dynamic-security file with the service users; False if one exists.

    Run before the broker first starts (scripts/setup.sh, the compose ``mqtt-init``
    service, the tests); the broker owns the file afterwards.
    """
    p = Path(path)
    if p.exists():
        return False
    p.parent.mkdir(parents=True, exist_ok=True)
    doc = {
        "defaultACLAccess": {
            "publishClientSend": False,
            "publishClientReceive": False,
            "subscribe": False,
            "unsubscribe": True,
        },
        "clients": [
            {"username": user, "textName": f"FieldRx {role}", "roles": [{"rolename": role}]}
            | _hashed(service_password(user))
            for user, role in ((ADMIN_USER, ADMIN_ROLE), (WORKER_USER, WORKER_ROLE))
        ],
        "groups": [],
        "roles": service_roles(),
    }
    tmp = p.with_suffix(".tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as f:
        json.dump(doc, f, indent=1)
    tmp.replace(p)
    _give_to_broker(p)
    return True


def _give_to_broker(path: Path) -> None:
    """Started as root, Mosquitto drops to the ``mosquitto`` user before it reads the
    file and writes its persistence next to it: hand both over."""
    if os.geteuid() != 0:
        return
    try:
        pw = pwd.getpwnam("mosquitto")
    except KeyError:
        return
    for p in (path.parent, path):
        os.chown(p, pw.pw_uid, pw.pw_gid)


# -- the admin channel -----------------------------------------------------------------


class DynsecAdmin:
    """A short-lived admin connection sending dynamic-security commands."""

    def __init__(self, url: str | None = None, timeout_s: float = 5.0) -> None:
        self.broker = Broker.from_url(url or get_settings().mqtt_url, ADMIN_USER)
        # the admin's own password, whatever user-info MQTT_URL carries for the workers
        self.broker = Broker(
            self.broker.host,
            self.broker.port,
            ADMIN_USER,
            service_password(ADMIN_USER),
            self.broker.tls,
        )
        self.timeout_s = timeout_s

    def run(self, commands: list[dict[str, Any]]) -> list[dict[str, Any]]:
        """Send commands in one message; their responses, in order."""
        done = threading.Event()
        ready = threading.Event()
        box: dict[str, Any] = {}
        client = mqtt.Client(
            mqtt.CallbackAPIVersion.VERSION2,
            client_id=f"fieldrx-admin-{uuid.uuid4().hex[:12]}",
            protocol=mqtt.MQTTv5,
        )
        self.broker.configure(client)

        def on_connect(c, userdata, flags, reason_code, properties) -> None:  # noqa: ANN001
            if reason_code.is_failure:
                box["error"] = f"connect refused: {reason_code}"
                done.set()
                return
            c.subscribe(CONTROL_TOPIC + "/response", qos=1)

        def on_subscribe(c, userdata, mid, reason_codes, properties) -> None:  # noqa: ANN001
            if any(rc.is_failure for rc in reason_codes):
                box["error"] = "not allowed to read the control topic"
                done.set()
            else:
                ready.set()

        def on_message(c, userdata, msg) -> None:  # noqa: ANN001
            box["responses"] = json.loads(msg.payload).get("responses", [])
            done.set()

        client.on_connect = on_connect
        client.on_subscribe = on_subscribe
        client.on_message = on_message
        try:
            client.connect(self.broker.host, self.broker.port, keepalive=10)
        except OSError as exc:
            raise MqttCredentialError(
                f"MQTT broker {self.broker.host}:{self.broker.port} unreachable: {exc}"
            ) from exc
        client.loop_start()
        try:
            if ready.wait(self.timeout_s):
                client.publish(CONTROL_TOPIC, json.dumps({"commands": commands}), qos=1)
            if not done.wait(self.timeout_s) or "error" in box:
                raise MqttCredentialError(
                    f"MQTT broker {self.broker.host}:{self.broker.port}: "
                    f"{box.get('error', 'no answer from the dynamic-security plugin')}"
                )
            return list(box["responses"])
        finally:
            client.disconnect()
            client.loop_stop()


def _check(responses: list[dict[str, Any]], tolerate_missing: int = 0) -> None:
    """Raise on any refused command; the first ``tolerate_missing`` may say "not found"."""
    for i, r in enumerate(responses):
        err = r.get("error")
        if err and not (i < tolerate_missing and "not found" in err):
            raise MqttCredentialError(f"MQTT broker refused {r.get('command')}: {err}")


def _delete_device_commands(machine_id: int) -> list[dict[str, Any]]:
    name = mqtt_username(machine_id)
    return [
        {"command": "deleteClient", "username": name},
        {"command": "deleteRole", "rolename": name},
    ]


def provision_device(machine_id: int, token: str) -> str:
    """(Re)create the machine's broker user with the token as password; its username.

    Called wherever a device token is issued (``issue_device_token``). Deleting the
    previous user first disconnects a session still using the previous token; the
    plugin runs the commands of one message in order.
    """
    name = mqtt_username(machine_id)
    if get_settings().mqtt_credentials == "off":
        return name
    create = [
        {"command": "createRole", "rolename": name, "acls": device_role(machine_id)["acls"]},
        {
            "command": "createClient",
            "username": name,
            "password": token,
            "clientid": mqtt_client_id(machine_id),
            "textName": f"machine {machine_id}",
            "roles": [{"rolename": name, "priority": 0}],
        },
    ]
    _check(DynsecAdmin().run(_delete_device_commands(machine_id) + create), tolerate_missing=2)
    return name


def revoke_device(machine_id: int) -> None:
    """Delete the machine's broker user and disconnect it (absent is fine).

    Called wherever a machine's current device token is revoked or the machine deleted.
    """
    if get_settings().mqtt_credentials == "off":
        return
    _check(DynsecAdmin().run(_delete_device_commands(machine_id)), tolerate_missing=2)


def revoke_device_after(machine_id: int, done: str) -> None:
    """:func:`revoke_device` after the database change ``done`` was committed: a revocation
    must not wait for the broker, but a broker that did not take it is reported (503)."""
    try:
        revoke_device(machine_id)
    except MqttCredentialError as exc:
        raise MqttCredentialError(
            f"{done}, but its MQTT credential is still on the broker ({exc}); "
            "`fieldrx mqtt-sync` deletes it once the broker answers"
        ) from exc


def sync_devices(session: Session) -> list[int]:
    """Delete the broker users of machines that have no live device token; their ids.

    Issuing and revoking keep the broker in step as they happen; this catches what
    happens by time or behind the API's back (a token that expired, rows deleted in
    SQL, a failed revoke). ``fieldrx mqtt-sync`` runs it; run it periodically (cron).
    """
    if get_settings().mqtt_credentials == "off":
        return []
    admin = DynsecAdmin()
    (listed,) = admin.run([{"command": "listClients", "verbose": False}])
    _check([listed])
    names = listed.get("data", {}).get("clients", [])
    on_broker = {
        int(n.removeprefix("machine-"))
        for n in names
        if isinstance(n, str) and n.startswith("machine-") and n[8:].isdigit()
    }
    live = set(
        session.scalars(
            select(ApiToken.machine_id).where(
                ApiToken.kind == "device",
                ApiToken.machine_id.in_(on_broker),
                ApiToken.revoked_at.is_(None),
                or_(ApiToken.expires_at.is_(None), ApiToken.expires_at > func.now()),
            )
        )
    )
    stale = sorted(on_broker - live)
    for machine_id in stale:
        revoke_device(machine_id)
    return stale


def next_device_expiry_s(session: Session) -> float | None:
    """Seconds until the next live device token expires (None: none will)."""
    left = session.scalar(
        select(func.min(func.extract("epoch", ApiToken.expires_at - func.now()))).where(
            ApiToken.kind == "device",
            ApiToken.revoked_at.is_(None),
            ApiToken.expires_at > func.now(),
        )
    )
    return None if left is None else float(left)
