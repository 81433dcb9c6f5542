"""`fieldrx worker`s on the real broker: shared subscription without loss or duplicates; a killed
worker (persistent session, stable slot) loses nothing."""

from __future__ import annotations

import json
import re
import threading
import time
import uuid

import pytest
from fieldrx_edge.protocol import ack_topic, telemetry_topic
from sqlalchemy import text

from tests.fleet.helpers import make_job, record
from tests.fleet.procs import start_worker
from tests.mqtt_broker import device_client
from tests.support import scaled


def test_two_workers_no_loss_no_duplicates(database_url, db, org) -> None:  # noqa: ANN001
    group = f"t{uuid.uuid4().hex[:8]}"
    workers = [start_worker(database_url, group), start_worker(database_url, group)]
    try:
        jobs = [make_job(org.id, state="running") for _ in range(4)]
        n_per_machine, batch = 600, 50
        acks: dict[int, int] = {}
        done = threading.Event()
        lock = threading.Lock()

        def on_message(client, userdata, msg) -> None:  # noqa: ANN001
            ack = json.loads(msg.payload)
            with lock:
                acks[ack["machine_id"]] = max(acks.get(ack["machine_id"], 0), ack["acked_seq"])
                if all(acks.get(j.machine_id) == n_per_machine for j in jobs):
                    done.set()

        # each machine logs in with its own credentials (user machine-<id>, its device token)
        devices = {j.machine_id: device_client(j.machine_id, j.device_token) for j in jobs}
        for j in jobs:
            devices[j.machine_id].on_message = on_message
            devices[j.machine_id].subscribe(ack_topic(j.machine_id), qos=1)
        time.sleep(0.3)
        infos = []
        t0 = 1_790_000_000.0
        for start in range(1, n_per_machine + 1, batch):
            for j in jobs:
                recs = [
                    record(j, s, t=t0 + s * 0.1, cell=(s // 40) % 8)
                    for s in range(start, start + batch)
                ]
                payload = json.dumps({"records": recs})
                pub = devices[j.machine_id]
                infos.append(pub.publish(telemetry_topic(j.machine_id), payload, qos=1))
                if start == 101:  # an edge resending a batch it got no ack for
                    infos.append(pub.publish(telemetry_topic(j.machine_id), payload, qos=1))
        for info in infos:
            info.wait_for_publish(10)
        assert done.wait(30), f"acks {acks}"
        for c in devices.values():
            c.disconnect()
            c.loop_stop()
        for j in jobs:
            row = db.execute(
                text(
                    "SELECT count(*), count(DISTINCT seq), min(seq), max(seq) FROM telemetry"
                    " WHERE machine_id = :m"
                ),
                {"m": j.machine_id},
            ).one()
            assert tuple(row) == (n_per_machine, n_per_machine, 1, n_per_machine)
    finally:
        logs = [w.stop() for w in workers]
    # both workers took part, and together they saw each record once plus the resent batches
    got = []
    for log in logs:
        m = re.search(r"records=(\d+), stored=(\d+), duplicates=(\d+)", log)
        assert m, log
        got.append(tuple(int(x) for x in m.groups()))
    assert all(g[1] > 0 for g in got), got
    assert sum(g[1] for g in got) == 4 * n_per_machine
    assert sum(g[2] for g in got) == 4 * batch


@pytest.mark.parametrize("n_workers", [1, 2])
def test_killed_worker_with_persistent_session_loses_nothing(
    database_url,
    db,
    org,
    n_workers: int,  # noqa: ANN001
) -> None:
    """SIGKILL a worker mid-stream while a publisher that never
    retransmits keeps going; the restarted worker takes the same slot, so the same broker
    session, and gets every unacknowledged and queued message. With two workers the dead
    member's share (the shared subscription keeps assigning it messages) arrives as soon
    as its slot is back, not after the session expiry."""
    group = f"k{uuid.uuid4().hex[:8]}"
    j = make_job(org.id, state="running")
    n_msgs, batch = 300, 20
    pub = device_client(j.machine_id, j.device_token)
    others = [start_worker(database_url, group) for _ in range(n_workers - 1)]
    worker = start_worker(database_url, group)  # the highest slot: killed and restarted
    restarted = None
    try:
        t0 = 1_790_000_000.0
        infos = []
        for i in range(n_msgs):
            recs = [
                record(j, s, t=t0 + s * 0.1, cell=(s // 40) % 8)
                for s in range(i * batch + 1, (i + 1) * batch + 1)
            ]
            infos.append(
                pub.publish(telemetry_topic(j.machine_id), json.dumps({"records": recs}), qos=1)
            )
            if i == n_msgs // 3:
                time.sleep(0.3)  # some stored, some in flight
                worker.p.kill()
                worker.p.wait()
            time.sleep(0.002)
        for info in infos:
            info.wait_for_publish(10)  # the broker has them all; the publisher is done
        restarted = start_worker(database_url, group)
        first_id = re.search(r"as (\S+) \(session", "\n".join(worker.lines))
        second_id = re.search(r"as (\S+) \(session", "\n".join(restarted.lines))
        assert first_id and second_id and first_id.group(1) == second_id.group(1)
        want = n_msgs * batch
        deadline = time.monotonic() + scaled(60)
        got = -1
        while time.monotonic() < deadline:
            got = db.execute(
                text("SELECT count(DISTINCT seq) FROM telemetry WHERE machine_id = :m"),
                {"m": j.machine_id},
            ).scalar_one()
            db.rollback()
            if got == want:
                break
            time.sleep(0.5)
        assert got == want
    finally:
        pub.disconnect()
        pub.loop_stop()
        for w in [worker, *others]:
            w.stop()
        if restarted is not None:
            restarted.stop()
