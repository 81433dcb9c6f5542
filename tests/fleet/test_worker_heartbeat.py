"""The worker touches its liveness file (read by the docker-compose health check)."""

from __future__ import annotations

import time
import uuid

from tests.fleet.procs import start_worker
from tests.support import scaled


def test_worker_touches_its_heartbeat_file(database_url, tmp_path) -> None:  # noqa: ANN001
    beat = tmp_path / "worker.alive"
    proc = start_worker(
        database_url, f"hb-{uuid.uuid4().hex[:6]}", env={"FIELDRX_WORKER_HEARTBEAT": str(beat)}
    )
    try:
        deadline = time.monotonic() + scaled(12)
        while not beat.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert beat.exists(), proc.lines[-10:]
        first = beat.stat().st_mtime
        time.sleep(5.5)
        assert beat.stat().st_mtime > first  # touched again at the next 5 s check
    finally:
        proc.stop()
    stopped = beat.stat().st_mtime
    time.sleep(0.5)
    assert beat.stat().st_mtime == stopped
