"""scale-out, the part that runs on one machine: two API processes and three MQTT
ingest workers on one database, agents over HTTP (behind a fail-over "load balancer")
and over MQTT; one API process and one worker are SIGKILLed mid-load. Every record is
stored exactly once: the agents resend what was not acknowledged, ingest deduplicates
by (machine, stream, seq) under its per-machine lock, whichever process gets the resend.
docs/scale.md has the topology this stands for."""

from __future__ import annotations

import os
import threading
import time
import uuid
from pathlib import Path
from urllib.parse import urlparse

from fieldrx_edge.protocol import mqtt_username
from fieldrx_edge.uplink.http import HttpSender
from fieldrx_edge.uplink.mqtt import MqttBroker, MqttSender
from fieldrx_edge.uplink.queue import TelemetryQueue
from sqlalchemy import text

from tests.fleet.helpers import JobFixture, make_job, record
from tests.fleet.procs import start_api, start_worker
from tests.support import scaled

N_RECORDS = 1500  # per machine
CHUNK = 25  # records the tractor queues every PERIOD_S
PERIOD_S = 0.1


def _produce(q: TelemetryQueue, fx: JobFixture, t0: float) -> None:
    for start in range(1, N_RECORDS + 1, CHUNK):
        q.put_many(
            [record(fx, s, t=t0 + s * 0.1, cell=(s // 40) % 8) for s in range(start, start + CHUNK)]
        )
        time.sleep(PERIOD_S)


def _http_agent(
    q: TelemetryQueue, urls: list[str], token: str, first: int, stop: threading.Event, stats: dict
) -> None:
    """The agent's HTTP sender behind a load balancer that routes away from a replica that
    does not answer (the production LB's health check, reduced to a fail-over)."""
    senders = [HttpSender(q, u, token, batch_size=100, timeout_s=scaled(5.0)) for u in urls]
    i = first
    while not stop.is_set():
        n = senders[i].send_once()
        if n is None:
            stats["failovers"] = stats.get("failovers", 0) + 1
            i = (i + 1) % len(senders)
            time.sleep(0.05)
        elif n == 0:
            time.sleep(0.05)
    for s in senders:
        s.close()


def test_api_and_worker_killed_mid_load_lose_and_duplicate_nothing(
    database_url: str,
    org,  # noqa: ANN001
    db,  # noqa: ANN001
    tmp_path: Path,
) -> None:
    group = f"s{uuid.uuid4().hex[:8]}"
    apis = [start_api(database_url) for _ in range(2)]
    urls = [u for _, u in apis]
    workers = [start_worker(database_url, group) for _ in range(3)]
    broker = urlparse(os.environ["MQTT_URL"])
    http_jobs = [make_job(org.id, state="running") for _ in range(3)]
    mqtt_jobs = [make_job(org.id, state="running") for _ in range(3)]
    queues = {
        fx.machine_id: TelemetryQueue(tmp_path / f"q{fx.machine_id}.sqlite", fx.machine_id)
        for fx in http_jobs + mqtt_jobs
    }
    stop = threading.Event()
    stats: dict[int, dict] = {fx.machine_id: {} for fx in http_jobs}
    threads = [
        threading.Thread(
            target=_http_agent,
            args=(queues[fx.machine_id], urls, fx.device_token, k % 2, stop, stats[fx.machine_id]),
            daemon=True,
        )
        for k, fx in enumerate(http_jobs)
    ]
    mqtt_senders = [
        MqttSender(
            queues[fx.machine_id],
            MqttBroker(
                broker.hostname or "127.0.0.1",
                broker.port or 1883,
                username=mqtt_username(fx.machine_id),
                password=fx.device_token,
            ),
            batch_size=50,
            ack_timeout_s=5.0,
        )
        for fx in mqtt_jobs
    ]
    threads += [threading.Thread(target=s.run, args=(stop,), daemon=True) for s in mqtt_senders]
    t0 = time.time() - 3600.0
    producers = [
        threading.Thread(target=_produce, args=(queues[fx.machine_id], fx, t0), daemon=True)
        for fx in http_jobs + mqtt_jobs
    ]
    total = N_RECORDS * len(queues)
    restarted = None
    try:
        for t in threads + producers:
            t.start()
        # mid-load: some records acknowledged, most not yet produced
        deadline = time.monotonic() + scaled(60)
        while sum(q.acked_seq for q in queues.values()) < total // 5:
            assert time.monotonic() < deadline, [q.acked_seq for q in queues.values()]
            time.sleep(0.05)
        acked_at_kill = sum(q.acked_seq for q in queues.values())
        apis[0][0].p.kill()  # SIGKILL: requests in flight die with it
        workers[0].p.kill()
        apis[0][0].p.wait()
        workers[0].p.wait()
        assert acked_at_kill < total // 2
        time.sleep(1.0)
        restarted = start_worker(database_url, group)  # the supervisor restarts the worker
        for p in producers:
            p.join(60)
        deadline = time.monotonic() + scaled(120)
        while any(q.backlog() or q.acked_seq < N_RECORDS for q in queues.values()):
            assert time.monotonic() < deadline, {
                m: (q.backlog(), q.acked_seq) for m, q in queues.items()
            }
            time.sleep(0.2)
    finally:
        stop.set()
        for t in threads:
            t.join(10)
        for s in mqtt_senders:
            s.close()
        for api, _ in apis:
            api.stop()
        logs = [w.stop() for w in workers[1:]] + ([restarted.stop()] if restarted else [])
    assert sum(s.get("failovers", 0) for s in stats.values()) > 0, "the API kill hit no agent"
    rows = db.execute(
        text(
            "SELECT machine_id, count(*), count(DISTINCT (stream, seq)), min(seq), max(seq)"
            " FROM telemetry WHERE machine_id = ANY(:m) GROUP BY machine_id"
        ),
        {"m": list(queues)},
    ).all()
    assert sorted(tuple(r[1:]) for r in rows) == [(N_RECORDS, N_RECORDS, 1, N_RECORDS)] * len(
        queues
    ), rows
    streams = db.execute(
        text(
            "SELECT machine_id, sum(n_records), max(acked_seq) FROM telemetry_streams"
            " WHERE machine_id = ANY(:m) GROUP BY machine_id"
        ),
        {"m": list(queues)},
    ).all()
    assert sorted(tuple(r[1:]) for r in streams) == [(N_RECORDS, N_RECORDS)] * len(queues)
    assert all("Traceback" not in log for log in logs), logs
