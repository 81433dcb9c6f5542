"""One bad record never blocks a tractor's uplink.

The agent's queue holds, among good records: a NaN HDOP written by an older
agent (raw JSON text with a NaN token, as Python's json.dumps wrote it), an
infinite HDOP and a negative speed (which today's agent sanitises before
queueing: null/clamped plus the ``invalid_value`` alarm), and a record stamped
in 2099. Through HTTP (real API server) and MQTT (real Mosquitto, real
`fieldrx worker`), the server rejects the NaN and the 2099 record alone with
a reason the agent counts, stores the rest, acknowledges past them, and the
agent's backlog drains. The 2099 record never becomes the machine's latest
state.
"""

from __future__ import annotations

import json
import sqlite3
import time
import uuid
from pathlib import Path

import pytest
from fieldrx_edge.protocol import mqtt_username
from fieldrx_edge.uplink import Backoff, HttpSender, MqttBroker, MqttSender, TelemetryQueue
from sqlalchemy import text

from tests.fleet.helpers import JobFixture, make_job, record
from tests.fleet.procs import start_api, start_worker
from tests.mqtt_broker import mqtt_port

T_2099 = 4_070_000_000.0


def _fill(q: TelemetryQueue, fx: JobFixture, t0: float) -> None:
    """seq 1-5 good, 6 NaN (raw, from an older agent), 7 inf hdop, 8 negative speed,
    9 stamped 2099, 10-30 good."""
    q.put_many([record(fx, 0, t=t0 + 0.1 * i) for i in range(5)])
    con = sqlite3.connect(q.path)
    bad = record(fx, 6, t=t0 + 0.5, hdop=float("nan"))
    with con:
        con.execute("INSERT INTO records VALUES (6, ?)", (json.dumps(bad),))
        con.execute("UPDATE meta SET value = 6 WHERE key = 'last_seq'")
    assert '"hdop": NaN' in con.execute("SELECT body FROM records WHERE seq = 6").fetchone()[0]
    con.close()
    q.put(record(fx, 0, t=t0 + 0.6, hdop=float("inf")))
    q.put(record(fx, 0, t=t0 + 0.7, speed_raw_m_s=-3.0))
    q.put(record(fx, 0, t=T_2099))
    q.put_many([record(fx, 0, t=t0 + 0.9 + 0.1 * i) for i in range(21)])
    assert q.last_seq == 30


def _check(db, q: TelemetryQueue, fx: JobFixture, t0: float) -> None:  # noqa: ANN001
    assert q.backlog() == 0
    assert q.stats()["sanitized"] == 2
    rows = db.execute(
        text(
            "SELECT seq, hdop, speed_raw_m_s, alarms FROM telemetry WHERE machine_id = :m"
            " ORDER BY seq"
        ),
        {"m": fx.machine_id},
    ).all()
    assert [r.seq for r in rows] == [s for s in range(1, 31) if s not in (6, 9)]
    by_seq = {r.seq: r for r in rows}
    assert by_seq[7].hdop is None and "invalid_value" in by_seq[7].alarms
    assert by_seq[8].speed_raw_m_s == 0.0 and "invalid_value" in by_seq[8].alarms
    assert by_seq[10].alarms == []
    rejected = q.stats()["reasons"]["rejected"]  # what `fieldrx-edge run` prints
    assert sum(rejected.values()) == 2 == q.stats()["rejected"]
    assert any("hdop must be a finite number" in r for r in rejected), rejected
    assert any("ahead of the server clock" in r for r in rejected), rejected
    last_t = db.execute(
        text("SELECT extract(epoch FROM last_t)::float8 FROM machine_status WHERE machine_id = :m"),
        {"m": fx.machine_id},
    ).scalar()
    assert last_t == pytest.approx(t0 + 0.9 + 2.0, abs=1e-3)  # seq 30, not 2099


def test_poison_records_over_http(database_url, org, db, tmp_path: Path) -> None:  # noqa: ANN001
    fx = make_job(org.id, state="running")
    t0 = time.time() - 60
    q = TelemetryQueue(tmp_path / "q.sqlite", fx.machine_id)
    _fill(q, fx, t0)
    api, url = start_api(database_url)
    try:
        s = HttpSender(q, url, fx.device_token, batch_size=8, backoff=Backoff(0.01, 0.05))
        assert s.drain(20), s.last_error
        s.close()
    finally:
        api.stop()
    _check(db, q, fx, t0)


def test_poison_records_over_mqtt(database_url, org, db, tmp_path: Path) -> None:  # noqa: ANN001
    fx = make_job(org.id, state="running")
    t0 = time.time() - 60
    q = TelemetryQueue(tmp_path / "q.sqlite", fx.machine_id)
    _fill(q, fx, t0)
    worker = start_worker(database_url, f"t{uuid.uuid4().hex[:8]}")
    host, port = mqtt_port()
    s = MqttSender(
        q,
        MqttBroker(host, port, username=mqtt_username(fx.machine_id), password=fx.device_token),
        batch_size=8,
        ack_timeout_s=3.0,
    )
    try:
        assert s.drain(30)
    finally:
        s.close()
        worker.stop()
    _check(db, q, fx, t0)
