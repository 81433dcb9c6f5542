import json
import threading
import time
import uuid

import pytest
from fieldrx.auth.mqtt import provision_device
from fieldrx_edge.protocol import ack_topic, mqtt_username, telemetry_topic
from fieldrx_edge.uplink import Backoff, HttpSender, MqttBroker, MqttSender, TelemetryQueue

from tests.mqtt_broker import mqtt_port, worker_client
from tests.support import scaled

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


def test_http_sender_uploads_a_partial_batch_once_per_period(tmp_path):
    """Online, the sender sent whenever anything was pending (every 0.2 s at 10 Hz): in
    real time a request's fixed server cost dwarfed its few records (docs/scale.md section
    5, seventh round). A batch that is not full now waits for the upload period; a full
    batch (a backlog) still goes at once; nothing is lost either way."""
    peer = Peer().start()
    stop = threading.Event()
    try:
        q = TelemetryQueue(tmp_path / "q.sqlite", machine_id=3)
        s = HttpSender(q, peer.url, "dev-token", batch_size=500, upload_period_s=0.5)
        th = threading.Thread(target=s.run, args=(stop,), daemon=True)
        th.start()
        t0 = time.monotonic()
        for i in range(40):  # 20 Hz for 2 s
            q.put(rec(i))
            time.sleep(0.05)
        uploads = s.sent_batches
        assert 3 <= uploads <= 2.0 / 0.5 + 2, uploads  # the first at once, then one per 0.5 s
        # a full batch right after an upload is not held for the period
        while q.backlog():
            time.sleep(0.02)
        s.pacer.period_s = 30.0
        q.put_many([rec(100 + i) for i in range(500)])
        t1 = time.monotonic()
        while q.backlog() and time.monotonic() - t1 < 10:
            time.sleep(0.02)
        assert q.backlog() == 0 and time.monotonic() - t1 < 5
        assert sorted(k[1] for k in peer.records) == list(range(1, 541))
        assert time.monotonic() - t0 < 20
    finally:
        stop.set()
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
    broker = MqttBroker(host, port, username=mqtt_username(q.machine_id), password=token)
    return MqttSender(q, broker, **kw)


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


def test_mqtt_sender_publishes_a_partial_batch_once_per_period(tmp_path):
    """As the HTTP sender: online, a batch that is not full waits for the upload period."""
    machine_id = 900_000_000 + uuid.uuid4().int % 99_999_999
    token = f"frx_d_{uuid.uuid4().hex}"
    provision_device(machine_id, token)
    srv = MqttServerPeer(machine_id)
    q = TelemetryQueue(tmp_path / "q.sqlite", machine_id=machine_id)
    s = _sender(q, token, batch_size=100, upload_period_s=0.5)
    messages = []
    srv_on_message = srv.on_message

    def counting(client, userdata, msg):
        messages.append(time.monotonic())
        srv_on_message(client, userdata, msg)

    srv.c.on_message = counting
    stop = threading.Event()
    th = threading.Thread(target=s.run, args=(stop,), daemon=True)
    th.start()
    try:
        time.sleep(0.5)  # connected
        for i in range(40):  # 20 Hz for 2 s
            q.put(rec(i))
            time.sleep(0.05)
        deadline = time.monotonic() + scaled(10)
        while q.backlog() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert sorted(srv.records) == list(range(1, 41)) and q.backlog() == 0
        assert 3 <= len(messages) <= 2.0 / 0.5 + 2, len(messages)
    finally:
        stop.set()
        th.join(5)
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
            timeout=scaled(60),
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


# (streams) and (nothing the protocol forbids is queued) ------------------


def test_queue_never_holds_a_record_the_protocol_forbids(tmp_path):
    q = TelemetryQueue(tmp_path / "q.sqlite", machine_id=3)
    seqs = q.put_many(
        [
            {**rec(0), "hdop": float("nan")},
            {**rec(1), "lon": float("inf")},
            {**rec(2), "t": float("nan")},  # no time: cannot be repaired
            {**rec(3), "duty": 250.0, "heading_deg": -90.0, "alarms": ["fix_lost"]},
            rec(4),
        ]
    )
    assert seqs == [1, 2, 3, 4]  # numbering stays contiguous around the dropped record
    body, n, last = q.pending_batch(10)
    obj = json.loads(body, parse_constant=lambda c: pytest.fail(f"{c} on the wire"))
    assert (n, last) == (4, 4)
    r1, r2, r3, r4 = obj["records"]
    assert r1["hdop"] is None and r1["alarms"] == ["invalid_value"]
    assert r2["lon"] is None and r2["lat"] is None and "invalid_value" in r2["alarms"]
    assert r3["duty"] == 100.0 and r3["heading_deg"] == 270.0
    assert r3["alarms"] == ["fix_lost", "invalid_value"]
    assert "invalid_value" not in r4.get("alarms", [])
    st = q.stats()
    assert (st["sanitized"], st["dropped"], st["last_seq"]) == (3, 1, 4)
    reasons = q.reasons()
    assert reasons["sanitized"] == {"hdop": 1, "lon/lat": 1, "duty": 1}
    assert list(reasons["dropped"]) == ["drop: t nan is not a positive finite unix time"]


def test_queue_streams_and_acks_of_other_streams(tmp_path):
    q = TelemetryQueue(tmp_path / "q.sqlite", machine_id=3)
    sid, start = q.stream
    assert len(sid) == 32 and start == 1
    q.put_many([rec(i) for i in range(10)])
    body = json.loads(q.pending_batch(4)[0])
    assert (body["format"], body["stream"], body["stream_start"]) == (2, sid, 1)
    assert [r["seq"] for r in body["records"]] == [1, 2, 3, 4]
    assert q.ack(8, stream="another-agent") == 0  # not this queue's stream
    assert q.ack(4, stream=sid, rejected=[{"seq": 2, "reason": "bad"}]) == 4
    assert q.reasons()["rejected"] == {"bad": 1} and q.stats()["rejected"] == 1
    new = q.new_stream()
    assert q.stream == (new, 5) and new != sid
    assert json.loads(q.pending_batch(10)[0])["stream_start"] == 5
    assert q.ack(10, stream=sid) == 0  # a late ack of the stream it left
    q.close()
    assert TelemetryQueue(tmp_path / "q.sqlite", machine_id=3).stream == (new, 5)
    assert TelemetryQueue(tmp_path / "other.sqlite", machine_id=3).stream[0] != new


def test_queue_database_from_before_streams_migrates(tmp_path):
    """A tractor's queue written by the format 1 agent keeps its pending records; they go on
    a new stream that starts after the acknowledged seq (nothing stored is sent again)."""
    import sqlite3

    path = tmp_path / "old.sqlite"
    con = sqlite3.connect(path)
    con.executescript(
        """
        CREATE TABLE records (seq INTEGER PRIMARY KEY, body TEXT NOT NULL);
        CREATE TABLE meta (key TEXT PRIMARY KEY, value INTEGER NOT NULL);
        INSERT INTO meta VALUES ('last_seq', 10), ('acked_seq', 6), ('rejected', 1),
            ('machine_id', 9);
        """
    )
    for s in range(7, 11):
        con.execute(
            "INSERT INTO records VALUES (?, ?)",
            (s, json.dumps({**rec(s), "machine_id": 9, "seq": s, "hdop": float("nan")})),
        )
    con.commit()
    con.close()
    q = TelemetryQueue(path, machine_id=9)
    st = q.stats()
    assert (st["last_seq"], st["acked_seq"], st["rejected"], st["backlog"]) == (10, 6, 1, 4)
    assert q.stream[1] == 7
    body = q.pending_batch(10)[0].decode()
    assert '"stream_start":7' in body and body.count("NaN") == 4  # sent as queued
    assert q.put(rec(11)) == 11


def test_http_sender_error_ack_trims_only_the_stored_batch(tmp_path, caplog):
    """A multi-batch answer where the server could not store one batch (its ack carries
    ``error`` and acked_seq 0, fleet.multibatch): the other queue is trimmed, this one
    keeps everything for the resend, and the server's reason is logged."""
    import httpx

    track = TelemetryQueue(tmp_path / "t.sqlite", machine_id=3)
    cells = TelemetryQueue(tmp_path / "c.sqlite", machine_id=3)
    track.put_many([rec(i) for i in range(5)])
    cells.put_many([rec(i) for i in range(3)])

    def answer(request: httpx.Request) -> httpx.Response:
        a, b = json.loads(request.content)["batches"]
        ok = {"machine_id": 3, "acked_seq": 5, "stored": 5, "duplicates": 0, "rejected": [],
              "stream": a["stream"], "stream_conflict": False}  # fmt: skip
        err = {**ok, "acked_seq": 0, "stored": 0, "stream": b["stream"],
               "error": "batches[1] (cells, stream x) not stored: no"}  # fmt: skip
        return httpx.Response(200, json={"acks": [ok, err]})

    s = HttpSender(track, "http://server", "t", extra_queues=(cells,))
    s._client = httpx.Client(transport=httpx.MockTransport(answer))
    with caplog.at_level("WARNING"):
        assert s.send_once() == 5
    assert (track.backlog(), cells.backlog()) == (0, 3)
    assert "batches[1] (cells, stream x) not stored" in caplog.text
    s.close()
