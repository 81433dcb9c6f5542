"""Real server processes for fleet tests: uvicorn API servers and `fieldrx worker`s."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx

from tests.support import scaled

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Proc:
    """A child process whose stderr is collected line by line."""

    def __init__(self, args: list[str], env: dict[str, str]) -> None:
        self.p = subprocess.Popen(
            args,
            cwd=ROOT,
            env={**os.environ, **env},
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        self.lines: list[str] = []
        self._t = threading.Thread(target=self._read, daemon=True)
        self._t.start()

    def _read(self) -> None:
        assert self.p.stderr is not None
        for line in self.p.stderr:
            self.lines.append(line.rstrip())

    def wait_for(self, text: str, timeout: float = 20.0) -> None:
        deadline = time.monotonic() + scaled(timeout)
        while time.monotonic() < deadline:
            if any(text in line for line in self.lines):
                return
            if self.p.poll() is not None:
                break
            time.sleep(0.05)
        raise AssertionError(f"{text!r} not seen; output: {self.lines[-20:]}")

    def stop(self, timeout: float = 10.0) -> str:
        if self.p.poll() is None:
            self.p.terminate()
            try:
                self.p.wait(scaled(timeout))
            except subprocess.TimeoutExpired:
                self.p.kill()
                self.p.wait()
        self._t.join(2)
        return "\n".join(self.lines)


def start_api(
    database_url: str, port: int | None = None, workers: int = 1, env: dict[str, str] | None = None
) -> tuple[Proc, str]:
    port = port or free_port()
    args = [
        str(BIN / "uvicorn"),
        "fieldrx.app:create_app",
        "--factory",
        "--host",
        "127.0.0.1",
        "--port",
        str(port),
        "--workers",
        str(workers),
        "--log-level",
        "warning",
        "--no-access-log",
    ]
    proc = Proc(args, {"DATABASE_URL": database_url, **(env or {})})
    url = f"http://127.0.0.1:{port}"
    # readiness is the health answer, and a crashed server ends the wait at once (poll
    # below); importing the app alone takes ~30 s on a loaded 2-core machine
    deadline = time.monotonic() + scaled(180)
    while time.monotonic() < deadline:
        try:
            if httpx.get(url + "/api/v1/health", timeout=scaled(1)).status_code < 500:
                return proc, url
        except httpx.HTTPError:
            pass
        if proc.p.poll() is not None:
            break
        time.sleep(0.1)
    raise AssertionError(f"API did not start: {proc.stop()}")


def start_worker(
    database_url: str,
    group: str,
    mqtt_url: str | None = None,
    batch_ms: int = 50,
    env: dict[str, str] | None = None,
) -> Proc:
    """A `fieldrx worker` on the session's broker (MQTT_URL, tests/conftest.py::mqtt_broker)
    with the workers' credentials; returns once its shared subscription is granted."""
    proc = Proc(
        [
            str(BIN / "fieldrx"),
            "worker",
            "--role",
            "ingest",
            "--group",
            group,
            "--batch-ms",
            str(batch_ms),
            "--mqtt-url",
            mqtt_url or os.environ["MQTT_URL"],
        ],
        {"DATABASE_URL": database_url, "FIELDRX_HEARTBEAT_TIMEOUT_S": "30", **(env or {})},
    )
    proc.wait_for("subscribed to")
    return proc
