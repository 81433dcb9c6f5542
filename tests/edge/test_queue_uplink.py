import json
import threading
import time
import uuid

import pytest
from fieldrx.auth.mqtt import provision_device
from fieldrx_edge.protocol import ack_topic, mqtt_username, telemetry_topic
from fieldrx_edge.uplink import Backoff, HttpSender, MqttSender, TelemetryQueue

from tests.mqtt_broker import mqtt_port, worker_client

from .peer import Peer


def rec(i):
    return {"t": 1_763_700_000.0 + i, "lon": 15.0, "lat": 52.0, "fix_quality": 4}


def test_queue_numbers_and_trims_only_to_ack(tmp_path):
    q = TelemetryQueue(tmp_path / "q.sqlite", machine_id=7)
    seqs = [q.put(rec(i)) for i in range(10)]
    assert seqs == list(range(1, 11))
    assert [r["seq"] for r in q.pending(4)] == [1, 2, 3, 4]
    assert all(r["machine_id"] == 7 for r in q.pending())
    assert q.ack(3) == 3
    assert [r["seq"] for r in q.pending(2)] == [4, 5]
    assert q.ack(2) == 0  # an older ack changes nothing
    assert q.ack(999) == 7  # never beyond what exists
    assert q.backlog() == 0
    q.close()
    q2 = TelemetryQueue(tmp_path / "q.sqlite", machine_id=7)
    assert q2.put(rec(11)) == 11  # numbering survives a restart
    with pytest.raises(ValueError):
        TelemetryQueue(tmp_path / "q.sqlite", machine_id=8)


def test_queue_concurrent_writer_and_reader(tmp_path):
    q = TelemetryQueue(tmp_path / "q.sqlite", machine_id=1)
    done = threading.Event()
    acked = []

    def reader():
        while not done.is_set() or q.backlog():
            batch = q.pending(50)
            if batch:
                q.ack(batch[-1]["seq"])
                acked.extend(r["seq"] for r in batch)

    th = threading.Thread(target=reader)
    th.start()
    for i in range(500):
        q.put(rec(i))
    done.set()
    th.join(10)
    assert acked == list(range(1, 501))


def test_backoff_grows_and_caps():
    import random

    b = Backoff(0.5, 4.0, random.Random(1))
    d = [b.next_delay() for _ in range(8)]
    assert d[0] <= 0.5 and d[3] > 1.0 and max(d) <= 4.0
    b.reset()
    assert b.next_delay() <= 0.5


def test_http_sender_retries_until_server_answers(tmp_path):
    peer = Peer().start()
    try:
        q = TelemetryQueue(tmp_path / "q.sqlite", machine_id=3)
        q.put_many([rec(i) for i in range(1200)])
        s = HttpSender(q, peer.url, "dev-token", batch_size=500, backoff=Backoff(0.01, 0.05))
        peer.fail_next = 3
        assert s.drain(20.0)
        assert s.failures == 3
        assert sorted(k[1] for k in peer.records) == list(range(1, 1201))
        assert peer.conflicts == 0
        bad = HttpSender(q, peer.url, "wrong", backoff=Backoff(0.01, 0.02))
        q.put(rec(0))
        assert bad.send_once() is None  # 401 is a failure, nothing trimmed
        assert q.backlog() == 1
        s.close()
        bad.close()
    finally:
        peer.stop()


def test_http_sender_unreachable_keeps_everything(tmp_path):
    q = TelemetryQueue(tmp_path / "q.sqlite", machine_id=3)
    q.put_many([rec(i) for i in range(10)])
    s = HttpSender(q, "http://127.0.0.1:9", "t", timeout_s=0.5, backoff=Backoff(0.01, 0.02))
    assert s.send_once() is None
    assert q.backlog() == 10


class MqttServerPeer:
    """Plays the server's MQTT worker (with the workers' credentials, on the session's
    broker from the shipped config): dedupe by seq, publish TelemetryAck."""

    def __init__(self, machine_id, drop_first=0):
        self.records = {}
        self.deliveries = 0
        self.drop_first = drop_first
        self.c = worker_client()
        self.topic = telemetry_topic(machine_id)
        self.ack = ack_topic(machine_id)
        self.c.on_message = self.on_message
        self.c.subscribe(self.topic, qos=1)
        time.sleep(0.3)

    def on_message(self, client, userdata, msg):
        body = json.loads(msg.payload)
        if self.drop_first > 0:
            self.drop_first -= 1  # the worker crashed before storing: no ack
            return
        for r in body["records"]:
            self.deliveries += 1
            self.records.setdefault(r["seq"], r)
        s = 0
        while s + 1 in self.records:
            s += 1
        client.publish(self.ack, json.dumps({"machine_id": 1, "acked_seq": s}), qos=1)

    def stop(self):
        self.c.loop_stop()
        self.c.disconnect()


def _sender(q, token, **kw):
    """The agent's sender logged in as its machine (user machine-<id>, the device token)."""
    host, port = mqtt_port()
    return MqttSender(
        q,
        host,
        port,
        username=mqtt_username(q.machine_id),
        password=token,
        **kw,
    )


def test_mqtt_sender_delivers_everything_once(tmp_path):
    machine_id = 900_000_000 + uuid.uuid4().int % 99_999_999
    token = f"frx_d_{uuid.uuid4().hex}"
    provision_device(machine_id, token)  # as issuing its device token does
    srv = MqttServerPeer(machine_id, drop_first=2)
    q = TelemetryQueue(tmp_path / "q.sqlite", machine_id=machine_id)
    q.put_many([rec(i) for i in range(5000)])
    s = _sender(q, token, batch_size=100, max_inflight_batches=10, ack_timeout_s=1.0)
    try:
        assert s.drain(30.0)
        assert sorted(srv.records) == list(range(1, 5001))
        assert q.backlog() == 0
    finally:
        s.close()
        srv.stop()


def test_mqtt_sender_with_a_wrong_token_sends_nothing(tmp_path):
    """No anonymous or mistaken login: the broker refuses it, and the queue stays intact."""
    machine_id = 900_000_000 + uuid.uuid4().int % 99_999_999
    provision_device(machine_id, "frx_d_the-real-token")
    srv = MqttServerPeer(machine_id)
    q = TelemetryQueue(tmp_path / "q.sqlite", machine_id=machine_id)
    q.put_many([rec(i) for i in range(50)])
    s = _sender(q, "frx_d_a-guess", ack_timeout_s=0.5)
    try:
        assert not s.drain(2.0)
        assert srv.deliveries == 0 and q.backlog() == 50
    finally:
        s.close()
        srv.stop()


def test_edge_cli_mqtt_logs_in_with_its_device_token(tmp_path):
    """`fieldrx-edge ... --mqtt HOST:PORT --token T` logs in as machine-<id> with the token
    and delivers everything; without the right token nothing is delivered."""
    import subprocess
    import sys

    machine_id = 900_000_000 + uuid.uuid4().int % 99_999_999
    token = f"frx_d_{uuid.uuid4().hex}"
    provision_device(machine_id, token)
    srv = MqttServerPeer(machine_id)
    f = tmp_path / "ndvi.csv"
    f.write_text("\n".join(f"{i * 0.1},0.3,0.31,0.29,0.3" for i in range(30)) + "\n")
    host, port = mqtt_port()

    def run(tok: str, state: str) -> dict:
        r = subprocess.run(
            [
                sys.executable,
                "-m",
                "fieldrx_edge.cli",
                "ndvi",
                f"file:{f}",
                "--json",
                "--machine-id",
                str(machine_id),
                "--state-dir",
                str(tmp_path / state),
                "--mqtt",
                f"{host}:{port}",
                "--token",
                tok,
                "--drain-timeout",
                "3",
            ],
            capture_output=True,
            text=True,
            check=True,
            timeout=60,
        )
        return json.loads(r.stdout)

    try:
        bad = run("frx_d_wrong", "a")
        assert bad["drained"] is False and srv.deliveries == 0
        good = run(token, "b")
        assert good["drained"] is True and good["samples"] == 30
        assert sorted(srv.records) == list(range(1, 31))
    finally:
        srv.stop()
