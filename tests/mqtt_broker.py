"""The project's broker for tests: Mosquitto started from the SHIPPED deploy/mosquitto.conf.

Only the listener port is changed (a free one), and the broker runs in a fresh
directory so its relative state paths (.run/mosquitto/: dynamic-security file,
persistence) are its own. The system Mosquitto on 1883 (anonymous) is never used.
"""

from __future__ import annotations

import os
import re
import shutil
import socket
import subprocess
import tempfile
import time
import uuid
from pathlib import Path

import paho.mqtt.client as mqtt

from tests.support import scaled

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "deploy" / "mosquitto.conf"
LISTENER = re.compile(r"^listener 1884 127\.0\.0\.1$", re.M)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class ProjectBroker:
    """One Mosquitto process; ``url`` is what MQTT_URL should say."""

    def __init__(self) -> None:
        from fieldrx.auth.mqtt import bootstrap

        text = SHIPPED.read_text()
        assert len(LISTENER.findall(text)) == 1, "shipped config: expected one 1884 listener"
        self.port = _free_port()
        self.dir = Path(tempfile.mkdtemp(prefix="fieldrx-mqtt-"))
        self.dir.chmod(0o755)  # Mosquitto drops to its own user when started as root
        conf = self.dir / "mosquitto.conf"
        conf.write_text(LISTENER.sub(f"listener {self.port} 127.0.0.1", text))
        bootstrap(self.dir / ".run" / "mosquitto" / "dynamic-security.json")
        self.url = f"mqtt://127.0.0.1:{self.port}"
        self.log = self.dir / "mosquitto.log"
        self.start()

    def start(self) -> None:
        with open(self.log, "ab") as log:
            self.proc = subprocess.Popen(
                ["mosquitto", "-c", str(self.dir / "mosquitto.conf")],
                cwd=self.dir,
                stdout=log,
                stderr=subprocess.STDOUT,
            )
        deadline = time.monotonic() + scaled(10)
        while time.monotonic() < deadline:
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=0.5).close()
                return
            except OSError:
                assert self.proc.poll() is None, self.log.read_text()
                time.sleep(0.05)
        raise AssertionError(f"broker did not start: {self.log.read_text()}")

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()

    def close(self) -> None:
        self.stop()
        shutil.rmtree(self.dir, ignore_errors=True)


def mqtt_port() -> tuple[str, int]:
    """Host and port of the broker in MQTT_URL (the test session's broker)."""
    from urllib.parse import urlparse

    u = urlparse(os.environ["MQTT_URL"])
    return u.hostname or "127.0.0.1", u.port or 1883


def connect(
    username: str | None,
    password: str | None,
    client_id: str | None = None,
    timeout_s: float = 5.0,
) -> tuple[mqtt.Client, mqtt.ReasonCode | None]:
    """An MQTT 5 client connected (or refused) to the session broker, its loop running;
    the CONNACK reason code, or None if none came."""
    got: list[mqtt.ReasonCode] = []
    c = mqtt.Client(
        mqtt.CallbackAPIVersion.VERSION2,
        client_id=client_id or f"t-{uuid.uuid4().hex[:10]}",
        protocol=mqtt.MQTTv5,
    )
    if username is not None:
        c.username_pw_set(username, password)
    c.on_connect = lambda c, u, f, rc, p: got.append(rc)
    c.reconnect_delay_set(0.2, 1)
    host, port = mqtt_port()
    c.connect(host, port, keepalive=30)
    c.loop_start()
    deadline = time.monotonic() + scaled(timeout_s)
    while not got and time.monotonic() < deadline:
        time.sleep(0.02)
    return c, (got[0] if got else None)


def device_client(machine_id: int, token: str) -> mqtt.Client:
    """A connected client with the machine's credentials (user machine-<id>, the token,
    its client id): one at a time per machine, as the broker allows."""
    from fieldrx_edge.protocol import mqtt_client_id, mqtt_username

    c, rc = connect(mqtt_username(machine_id), token, mqtt_client_id(machine_id))
    assert rc is not None and not rc.is_failure, rc
    return c


def worker_client() -> mqtt.Client:
    """A connected client with the ingest workers' credentials."""
    from fieldrx.auth.mqtt import WORKER_USER, service_password

    c, rc = connect(WORKER_USER, service_password(WORKER_USER))
    assert rc is not None and not rc.is_failure, rc
    return c
