"""MQTT authentication and authorisation on the real broker with the SHIPPED configuration.

anonymous clients stored forged records for other organisations'
machines, a ``#`` subscriber read every organisation's telemetry and acks, and a
forged ack made an agent delete unsent records. The session broker
(tests/conftest.py::mqtt_broker) runs deploy/mosquitto.conf unchanged but for its port.
"""

from __future__ import annotations

import json
import threading
import time
import uuid

import paho.mqtt.client as mqtt
import pytest
from fieldrx_edge.protocol import (
    ack_topic,
    jobs_topic,
    mqtt_client_id,
    mqtt_username,
    telemetry_topic,
)
from sqlalchemy import text

from tests.fleet.helpers import make_job, record
from tests.fleet.procs import start_worker
from tests.mqtt_broker import SHIPPED, connect, device_client, worker_client


class Sub:
    """Subscribe and collect messages; ``granted`` holds each SUBACK's reason codes."""

    def __init__(self, client: mqtt.Client) -> None:
        self.c = client
        self.got: list[tuple[str, bytes]] = []
        self.acks: dict[int, list[mqtt.ReasonCode]] = {}
        self.cv = threading.Condition()
        client.on_message = self._msg
        client.on_subscribe = self._sub

    def _msg(self, c, u, m) -> None:  # noqa: ANN001
        with self.cv:
            self.got.append((m.topic, m.payload))
            self.cv.notify_all()

    def _sub(self, c, u, mid, rcs, p) -> None:  # noqa: ANN001
        with self.cv:
            self.acks[mid] = list(rcs)
            self.cv.notify_all()

    def subscribe(self, topic: str) -> bool:
        """True when the broker granted the subscription."""
        _, mid = self.c.subscribe(topic, qos=1)
        with self.cv:
            assert self.cv.wait_for(lambda: mid in self.acks, 5), topic
            return not self.acks[mid][0].is_failure

    def wait(self, n: int, timeout: float = 5.0) -> bool:
        with self.cv:
            return self.cv.wait_for(lambda: len(self.got) >= n, timeout)


def _close(*clients: mqtt.Client) -> None:
    for c in clients:
        c.disconnect()
        c.loop_stop()


def _publish_refused(machine_id: int, token: str, topic: str, payload: str) -> bool:
    """Publish QoS 1 as the machine on a fresh connection; True if the broker's PUBACK
    says "Not authorized" (Mosquitto then also closes the connection)."""
    c = device_client(machine_id, token)
    acked: list[mqtt.ReasonCode] = []
    done = threading.Event()

    def on_publish(cl, u, mid, rc, p) -> None:  # noqa: ANN001
        acked.append(rc)
        done.set()

    c.on_publish = on_publish
    c.publish(topic, payload, qos=1)
    done.wait(5)
    _close(c)
    return bool(acked) and acked[0].is_failure and "authori" in str(acked[0]).lower()


def test_shipped_config_has_no_anonymous_listener() -> None:
    for conf in SHIPPED.parent.glob("mosquitto*.conf"):
        lines = [ln.split("#")[0].split() for ln in conf.read_text().splitlines()]
        settings = {ln[0]: ln[1:] for ln in lines if ln}
        assert settings.get("allow_anonymous") == ["false"], conf
        assert settings.get("per_listener_settings", ["false"]) == ["false"], conf
        assert "plugin" in settings, conf


def test_anonymous_and_wrong_password_are_refused(database_url, org) -> None:  # noqa: ANN001
    j = make_job(org.id, state="running")
    for user, password in ((None, None), (mqtt_username(j.machine_id), "frx_d_not-the-token")):
        c, rc = connect(user, password)
        try:
            assert rc is not None and rc.is_failure, (user, rc)
            assert not c.is_connected()
        finally:
            _close(c)


def test_device_can_only_use_its_own_topics(database_url, make_org) -> None:  # noqa: ANN001
    """Two organisations' machines: A cannot publish as B, read B or '#', nor forge acks."""
    a = make_job(make_org().id, state="running")
    b = make_job(make_org().id, state="running")
    spy = Sub(device_client(a.machine_id, a.device_token))
    assert not spy.subscribe("#")
    assert not spy.subscribe("fieldrx/#")
    assert not spy.subscribe(telemetry_topic(b.machine_id))
    assert not spy.subscribe(ack_topic(b.machine_id))
    assert not spy.subscribe(jobs_topic(b.machine_id))
    assert not spy.subscribe(f"$share/x/{telemetry_topic(b.machine_id)}")
    assert spy.subscribe(ack_topic(a.machine_id))
    assert spy.subscribe(jobs_topic(a.machine_id))
    _close(spy.c)  # one connection per machine: the forgeries below use fresh ones

    watcher = Sub(worker_client())  # sees every telemetry message that gets through
    assert watcher.subscribe("fieldrx/machines/+/telemetry")
    victim = Sub(device_client(b.machine_id, b.device_token))
    assert victim.subscribe(ack_topic(b.machine_id))
    forged = json.dumps({"records": [record(b, 1)]})
    fake_ack = json.dumps({"machine_id": b.machine_id, "acked_seq": 100})
    try:
        for topic, payload in (
            (telemetry_topic(b.machine_id), forged),
            (ack_topic(b.machine_id), fake_ack),
            (ack_topic(a.machine_id), fake_ack),
        ):
            assert _publish_refused(a.machine_id, a.device_token, topic, payload), topic
        # B's own telemetry still flows: the broker dropped only the forgeries
        victim.c.publish(telemetry_topic(b.machine_id), "{}", qos=1).wait_for_publish(5)
        assert watcher.wait(1)
        time.sleep(0.5)
        assert watcher.got == [(telemetry_topic(b.machine_id), b"{}")]
        assert victim.got == []  # no forged ack reached B
    finally:
        _close(watcher.c, victim.c)


def test_forged_records_never_reach_the_database(database_url, db, make_org) -> None:  # noqa: ANN001
    """Through a real worker: A's forgery for B stores nothing; A's own record is stored."""
    a = make_job(make_org().id, state="running")
    b = make_job(make_org().id, state="running")
    worker = start_worker(database_url, f"sec{uuid.uuid4().hex[:6]}")
    forged = json.dumps({"records": [record(b, 1)]})
    assert _publish_refused(a.machine_id, a.device_token, telemetry_topic(b.machine_id), forged)
    acks = Sub(device_client(a.machine_id, a.device_token))
    try:
        assert acks.subscribe(ack_topic(a.machine_id))
        # a record naming B on A's own topic is rejected by the worker's record check
        own = [record(a, 1), {**record(a, 2), "machine_id": b.machine_id}]
        acks.c.publish(
            telemetry_topic(a.machine_id), json.dumps({"records": own}), qos=1
        ).wait_for_publish(5)
        assert acks.wait(1), worker.lines[-10:]  # processed (the ack's content is ingest's)
    finally:
        _close(acks.c)
        worker.stop()
    counts = dict(
        db.execute(
            text(
                "SELECT machine_id, count(*) FROM telemetry WHERE machine_id IN (:a, :b)"
                " GROUP BY machine_id"
            ),
            {"a": a.machine_id, "b": b.machine_id},
        ).all()
    )
    assert counts == {a.machine_id: 1}


def test_device_token_response_names_the_mqtt_user(client, org, database_url) -> None:  # noqa: ANN001
    j = make_job(org.id)
    r = client.post(f"/api/v1/machines/{j.machine_id}/device-token", headers=org.headers())
    assert r.status_code == 201, r.text
    body = r.json()
    assert body["mqtt_username"] == mqtt_username(j.machine_id)
    c = device_client(j.machine_id, body["token"])
    _close(c)


def _refused(machine_id: int, token: str, client_id: str | None = None) -> bool:
    c, rc = connect(mqtt_username(machine_id), token, client_id or mqtt_client_id(machine_id))
    _close(c)
    return rc is not None and rc.is_failure


def test_device_cannot_take_over_another_session(database_url, org) -> None:  # noqa: ANN001
    """A device reusing a worker's (or another machine's) client id would disconnect it and
    take over its session: the broker accepts a machine only under its own client id."""
    from fieldrx.auth.mqtt import WORKER_USER, service_password

    a, b = make_job(org.id), make_job(org.id)
    worker_id = f"fieldrx-worker-sec{uuid.uuid4().hex[:6]}-node-0"
    worker, rc = connect(WORKER_USER, service_password(WORKER_USER), worker_id)
    assert rc is not None and not rc.is_failure
    kicked = threading.Event()
    worker.on_disconnect = lambda *args: kicked.set()
    try:
        assert _refused(a.machine_id, a.device_token, client_id=worker_id)
        assert _refused(a.machine_id, a.device_token, client_id=mqtt_client_id(b.machine_id))
        assert not kicked.wait(0.5) and worker.is_connected()
        assert not _refused(a.machine_id, a.device_token)
    finally:
        _close(worker)


def test_reissued_token_replaces_the_mqtt_credential(client, org, database_url) -> None:  # noqa: ANN001
    """Issuing a new device token revokes the old one: its MQTT login is refused and a
    live connection made with it is dropped."""
    j = make_job(org.id)
    live = device_client(j.machine_id, j.device_token)
    dropped = threading.Event()
    live.on_disconnect = lambda *a: dropped.set()
    r = client.post(f"/api/v1/machines/{j.machine_id}/device-token", headers=org.headers())
    assert r.status_code == 201, r.text
    try:
        assert dropped.wait(5)
        assert _refused(j.machine_id, j.device_token)
        assert not _refused(j.machine_id, r.json()["token"])
    finally:
        _close(live)


@pytest.mark.parametrize("how", ["revoke", "delete-machine"])
def test_revoked_device_token_stops_working_on_mqtt(client, db, org, database_url, how) -> None:  # noqa: ANN001
    j = make_job(org.id)
    r = client.post(f"/api/v1/machines/{j.machine_id}/device-token", headers=org.headers())
    token = r.json()["token"]
    assert not _refused(j.machine_id, token)
    live = device_client(j.machine_id, token)
    dropped = threading.Event()
    live.on_disconnect = lambda *a: dropped.set()
    if how == "revoke":
        token_id = db.execute(
            text("SELECT id FROM api_tokens WHERE machine_id = :m AND revoked_at IS NULL"),
            {"m": j.machine_id},
        ).scalar_one()
        r = client.delete(f"/api/v1/auth/tokens/{token_id}", headers=org.headers("admin"))
    else:
        db.execute(text("DELETE FROM jobs WHERE machine_id = :m"), {"m": j.machine_id})
        db.commit()
        r = client.delete(f"/api/v1/machines/{j.machine_id}", headers=org.headers())
    assert r.status_code == 204, r.text
    try:
        assert dropped.wait(5)
        assert _refused(j.machine_id, token)
    finally:
        _close(live)


def test_token_is_not_issued_when_the_broker_cannot_take_its_credential(
    client,
    db,
    org,
    database_url,
    monkeypatch,  # noqa: ANN001
) -> None:
    """Broker down: 503 saying so, and no token row left behind."""
    from fieldrx.settings import get_settings

    j = make_job(org.id)
    before = db.execute(
        text("SELECT count(*) FROM api_tokens WHERE machine_id = :m"), {"m": j.machine_id}
    ).scalar_one()
    monkeypatch.setattr(get_settings(), "mqtt_url", "mqtt://127.0.0.1:9")
    r = client.post(f"/api/v1/machines/{j.machine_id}/device-token", headers=org.headers())
    assert r.status_code == 503 and "MQTT broker" in r.json()["detail"], r.text
    after = db.execute(
        text("SELECT count(*) FROM api_tokens WHERE machine_id = :m"), {"m": j.machine_id}
    ).scalar_one()
    assert after == before


def test_sync_deletes_credentials_of_expired_or_sql_revoked_tokens(db, org, database_url) -> None:  # noqa: ANN001
    """Expiry happens by time, not through an API call: `fieldrx mqtt-sync` removes the
    broker users of machines whose device token expired or was revoked behind the API's back."""
    from fieldrx.auth.mqtt import sync_devices

    expired, revoked, live = (make_job(org.id) for _ in range(3))
    db.execute(
        text("UPDATE api_tokens SET expires_at = now() - interval '1 s' WHERE machine_id = :m"),
        {"m": expired.machine_id},
    )
    db.execute(
        text("UPDATE api_tokens SET revoked_at = now() WHERE machine_id = :m"),
        {"m": revoked.machine_id},
    )
    db.commit()
    assert not _refused(expired.machine_id, expired.device_token)  # until the sync
    stale = sync_devices(db)
    assert {expired.machine_id, revoked.machine_id} <= set(stale)
    assert live.machine_id not in stale
    assert _refused(expired.machine_id, expired.device_token)
    assert _refused(revoked.machine_id, revoked.device_token)
    assert not _refused(live.machine_id, live.device_token)
    assert live.machine_id not in sync_devices(db)  # idempotent, live users stay


def test_revoking_with_the_broker_down_revokes_and_says_the_credential_is_left(
    client, db, org, database_url, monkeypatch
) -> None:  # noqa: ANN001
    """A revocation never waits for the broker: the token is revoked, the 503 says its MQTT
    credential is still there, and `fieldrx mqtt-sync` removes it once the broker answers."""
    from fieldrx.auth.mqtt import sync_devices
    from fieldrx.settings import get_settings

    j = make_job(org.id)
    token_id = db.execute(
        text("SELECT id FROM api_tokens WHERE machine_id = :m AND revoked_at IS NULL"),
        {"m": j.machine_id},
    ).scalar_one()
    url = get_settings().mqtt_url
    monkeypatch.setattr(get_settings(), "mqtt_url", "mqtt://127.0.0.1:9")
    r = client.delete(f"/api/v1/auth/tokens/{token_id}", headers=org.headers("admin"))
    assert r.status_code == 503, r.text
    assert "is revoked" in r.json()["detail"] and "mqtt-sync" in r.json()["detail"]
    assert client.get("/api/v1/device/jobs", headers=j.device_headers).status_code == 401
    monkeypatch.setattr(get_settings(), "mqtt_url", url)
    assert not _refused(j.machine_id, j.device_token)
    assert j.machine_id in sync_devices(db)
    assert _refused(j.machine_id, j.device_token)


def test_expired_device_token_is_refused_by_the_broker_at_expiry(db, org) -> None:  # noqa: ANN001
    """An expired device token still logged in to MQTT until `fieldrx mqtt-sync` ran from
    cron: every task worker now removes the broker user right after the token expires."""
    import asyncio
    import contextlib

    from fieldrx.tasks.worker import expire_device_credentials

    j = make_job(org.id)
    db.execute(
        text("UPDATE api_tokens SET expires_at = now() + interval '3 s' WHERE machine_id = :m"),
        {"m": j.machine_id},
    )
    db.commit()
    assert not _refused(j.machine_id, j.device_token)
    loop = asyncio.new_event_loop()
    task = loop.create_task(expire_device_credentials(3600.0))  # no periodic pass: at expiry

    def run() -> None:
        with contextlib.suppress(asyncio.CancelledError):
            loop.run_until_complete(task)

    runner = threading.Thread(target=run, daemon=True)
    runner.start()
    try:
        deadline = time.monotonic() + 60
        while not _refused(j.machine_id, j.device_token):
            assert time.monotonic() < deadline, "the expired token still logs in"
            time.sleep(0.5)
    finally:
        loop.call_soon_threadsafe(task.cancel)
        runner.join(10)
