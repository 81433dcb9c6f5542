"""Telemetry ingest benchmark: N simulated machines through HTTP or MQTT into PostGIS.

Everything runs against a throw-away database: this script starts its own API
server (uvicorn, ``--workers`` processes on a free port) or, for MQTT, its own
Mosquitto (the project's deploy/mosquitto.conf on a free port: no anonymous
clients, each machine logs in with its device token) and ``--workers`` (default 2)
``fieldrx worker`` processes sharing the subscription, each with its default lanes
(FIELDRX_WORKER_DB_CONNECTIONS; ``--db-connections`` overrides): one worker per core,
as docs/scale.md sizes them.

Each machine has ``hz * seconds`` records (default 200 machines x 10 Hz x 60 s
= 120,000). They are replayed as fast as the server accepts them (a fleet
catching up after being offline): each machine sends its records in order in
batches (``--batch``, the edge agent's default), waiting for the ack before
the next batch like the real agent; records are stamped when their batch is
built, so latency = ack received - record time. With ``--realtime`` machines
produce at ``hz`` and send every ``--send-every`` seconds instead (over HTTP the thin
phase too, every ``--thin-send-every`` s: each period's track records and the cells left
in it, ``thin_realtime_bodies``; both default to the agents' upload periods).

Baseline, same run: a raw COPY BINARY of the same rows (prepared tuples,
10,000 rows per COPY) into a copy of the telemetry table with the same
indexes. Ratio = our records/s / raw COPY records/s. Against a Citus coordinator
(``--database-url``) the copy is distributed by machine and co-located with telemetry, so
the baseline pays the same routing to the workers; the CPU per record then counts every
node's backends of the bench database (a one-host cluster here).

Then the same machine-hours with uplink profile ``thin`` (a 1 Hz track plus
one cell record per cell left, on two streams; over HTTP both in one request while both
have records, as the HTTP sender sends them; over MQTT one batch per message, as the MQTT
sender does): the server's CPU (API processes or MQTT workers and broker, and the
PostgreSQL backends of the bench database, process CPU time) per machine-hour of both,
and their ratio (``thin``; ``--no-thin`` skips it). Each machine's drive is replayed as a
backlog in batches of ``--batch`` records, so the thin ratio depends on ``--seconds``: a
request's fixed cost (token, transaction, statements) is paid per batch, and a
one-minute thin backlog is a single small request where the full profile sends two
large ones (docs/scale.md section 5, seventh round).

Last line: one JSON object (records_per_s, raw_copy_records_per_s,
ratio_to_copy, p50_latency_s, p99_latency_s, lost, duplicated, thin, ...).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from fieldrx_edge.protocol import UPLOAD_PERIOD_S  # noqa: E402

from tests import citus_cluster  # noqa: E402
from tests.mqtt_broker import ProjectBroker  # noqa: E402

BIN = Path(sys.executable).parent
PG = os.environ.get("FIELDRX_TEST_PG", "postgresql://postgres@127.0.0.1:5432")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# database ----------------------------------------------------------------------------
def make_db() -> str:
    from alembic import command
    from fieldrx.db.bootstrap import alembic_config, ensure_database

    url = (
        PG.replace("postgresql://", "postgresql+psycopg://", 1)
        + f"/fieldrx_bench_{uuid.uuid4().hex[:8]}"
    )
    ensure_database(url)
    if citus_cluster.WORKERS:  # FIELDRX_TEST_PG is a Citus coordinator
        citus_cluster.prepare(url)
    command.upgrade(alembic_config(url), "head")
    if citus_cluster.WORKERS:
        citus_cluster.distribute_db(url)
    return url


def seed(url: str, n_machines: int) -> list[tuple[int, int, str]]:
    """An organisation, one field/plan/prescription, and per machine a running job + token."""
    from fieldrx.auth.service import create_organisation, issue_device_token
    from fieldrx.db.models import Field, Job, Machine, Plan, Prescription, PrescriptionVersion
    from fieldrx.db.session import make_engine
    from geoalchemy2.shape import from_shape
    from shapely.geometry import LineString, MultiPolygon, Polygon
    from sqlalchemy.orm import Session

    eng = make_engine(url)
    out = []
    with Session(eng) as s:
        org = create_organisation(s, f"bench-{uuid.uuid4().hex[:6]}")
        f = Field(
            organisation_id=org.id,
            name="bench",
            boundary=from_shape(
                MultiPolygon([Polygon.from_bounds(112.3, 32.1, 112.33, 32.14)]), 4326
            ),
            utm_epsg=32649,
            area_m2=1e6,
        )
        s.add(f)
        s.flush()
        p = Plan(
            organisation_id=org.id,
            field_id=f.id,
            params={},
            metrics={},
            heading_deg=0.0,
            n_cells=1000,
            route=from_shape(LineString([(112.3, 32.1), (112.31, 32.11)]), 4326),
        )
        s.add(p)
        s.flush()
        rx = Prescription(organisation_id=org.id, plan_id=p.id, model="uniform")
        s.add(rx)
        s.flush()
        s.add(PrescriptionVersion(prescription_id=rx.id, version=1))
        for i in range(n_machines):
            m = Machine(
                organisation_id=org.id,
                name=f"m{i}",
                width_m=6.0,
                lag_s=1.5,
                calibration={"kind": "linear", "a": 1.0, "b": 0.0},
                controller={},
                speed_min_m_s=0.5,
                speed_max_m_s=3.0,
            )
            s.add(m)
            s.flush()
            j = Job(
                organisation_id=org.id,
                prescription_id=rx.id,
                prescription_version=1,
                machine_id=m.id,
                state="running",
                n_cells=1000,
            )
            s.add(j)
            s.flush()
            out.append((m.id, j.id, issue_device_token(s, m.id, org.id)))
        s.commit()
    eng.dispose()
    return out


# records -----------------------------------------------------------------------------
class Fleet:
    """Per machine: a straight track at ~1.7 m/s, on target, one cell per 3 s."""

    def __init__(self, machines: list[tuple[int, int, str]], hz: float, seconds: float) -> None:
        self.machines = machines
        self.hz = hz
        self.n = int(round(hz * seconds))
        self._parts: list[list[tuple[str, str]]] = []

    def prepare(self) -> None:
        """Pre-render every record's JSON around its time stamp, so the simulated fleet costs
        the shared 2 cores little while it runs (real agents run elsewhere)."""
        for k in range(len(self.machines)):
            parts = [("", "")]  # seq 0 unused
            for rec in self.records(k, 1, self.n, 0.0):
                rec["t"] = 0.0
                text = json.dumps(rec, separators=(",", ":"))
                head, tail = text.split('"t":0.0', 1)
                parts.append((head + '"t":', tail))
            self._parts.append(parts)

    def body(self, k: int, seq: int, times: list[float]) -> str:
        parts = self._parts[k]
        return (
            f'{{"format":2,"stream":"bench{k}","stream_start":1,"records":['
            + ",".join(f"{parts[seq + i][0]}{t!r}{parts[seq + i][1]}" for i, t in enumerate(times))
            + "]}"
        )

    def records(self, k: int, seq0: int, count: int, t_now: float) -> list[dict[str, Any]]:
        mid, jid, _ = self.machines[k]
        out = []
        dt = 1.0 / self.hz
        for i in range(count):
            seq = seq0 + i
            s = seq * dt * 1.7
            out.append(
                {
                    "machine_id": mid,
                    "seq": seq,
                    "t": t_now - (count - 1 - i) * 1e-6,
                    "lon": 112.3 + k * 1e-4,
                    "lat": 32.1 + s * 9e-6,
                    "fix_quality": 4,
                    "hdop": 0.7,
                    "speed_raw_m_s": 1.7 + (seq % 7) * 0.01,
                    "speed_filtered_m_s": 1.7,
                    "heading_deg": 0.0,
                    "job_id": jid,
                    "cell_seq": int(seq * dt / 3.0) % 1000,
                    "target_rate_kg_ha": 300.0,
                    "applied_rate_kg_ha": 299.0 + (seq % 3),
                    "target_shaft_rpm": 30.0,
                    "actual_shaft_rpm": 29.9,
                    "duty": 41.5,
                    "ndvi": None,
                    "depth_mm": None,
                    "implement_down": True,
                    "alarms": [],
                    "queue_backlog": self.n - seq,
                    "fix_period_s": dt,
                }
            )
        return out


def citus(conn: Any) -> bool:
    """Whether the bench database is a Citus coordinator's (``fieldrx distribute`` done)."""
    return bool(
        conn.execute(
            "SELECT EXISTS (SELECT 1 FROM pg_extension WHERE extname = 'citus')"
        ).fetchone()[0]
    )


def raw_copy_baseline(url: str, fleet: Fleet) -> float:
    """records/s of a plain COPY BINARY of the same rows into a table like telemetry
    (same columns and indexes; 10,000 rows per COPY, one connection): median of thirds."""
    import psycopg
    from fieldrx.db.session import raw_dsn
    from fieldrx.fleet.ingest.validate import validate
    from fieldrx.fleet.telemetry_row import TELEMETRY_COPY

    rows: list[tuple[Any, ...]] = []
    t_now = time.time()
    for k in range(len(fleet.machines)):
        valid, *_ = validate(fleet.records(k, 1, fleet.n, t_now), fleet.machines[k][0])
        rows.extend(valid.values())
    cols = ", ".join(TELEMETRY_COPY.columns)
    with psycopg.connect(raw_dsn(url), options="-c jit=off", autocommit=True) as conn:
        conn.execute("CREATE TABLE telemetry_baseline (LIKE telemetry INCLUDING ALL)")
        if citus(conn):  # on a cluster: sharded like telemetry, so both pay the routing
            conn.execute(
                "SELECT create_distributed_table('telemetry_baseline', 'machine_id',"
                " colocate_with => 'telemetry')"
            )
        # same indexes (INCLUDING ALL: primary key, btrees, GiST) and the same foreign key
        conn.execute(
            "ALTER TABLE telemetry_baseline ADD FOREIGN KEY (machine_id) REFERENCES machines (id)"
        )
        # three thirds of the rows, timed separately: the median resists a burst of load
        # from other processes on the machine
        rates = []
        third = -(-len(rows) // 3)
        for part in range(3):
            chunk_rows = rows[part * third : (part + 1) * third]
            t0 = time.perf_counter()
            for i in range(0, len(chunk_rows), 10_000):
                with conn.transaction(), conn.cursor() as cur:
                    with cur.copy(
                        f"COPY telemetry_baseline ({cols}) FROM STDIN (FORMAT BINARY)"
                    ) as cp:
                        cp.set_types(TELEMETRY_COPY.types)
                        for r in chunk_rows[i : i + 10_000]:
                            cp.write_row(r)
            rates.append(len(chunk_rows) / (time.perf_counter() - t0))
        n = conn.execute("SELECT count(*) FROM telemetry_baseline").fetchone()[0]
        assert n == len(rows), (n, len(rows))
        conn.execute("DROP TABLE telemetry_baseline")
        conn.execute("CHECKPOINT")
    print("raw COPY thirds: " + ", ".join(f"{r:,.0f}" for r in rates) + " records/s")
    return float(np.median(rates))


# processes ---------------------------------------------------------------------------
def start(args: list[str], env: dict[str, str], log: Path | None = None) -> subprocess.Popen[bytes]:
    err: Any = log.open("wb") if log is not None else subprocess.PIPE
    return subprocess.Popen(
        args, cwd=ROOT, env={**os.environ, **env}, stdout=subprocess.DEVNULL, stderr=err
    )


def wait_log(paths: list[Path], text: str, timeout: float = 180.0) -> None:
    """Wait until every log file contains ``text`` (e.g. each worker has subscribed:
    a message published before any subscription exists is dropped by the broker). Long
    timeouts: under load (8 helpers on 2 cores) importing the app took 40 s."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if all(p.exists() and text in p.read_text(errors="replace") for p in paths):
            return
        time.sleep(0.1)
    raise SystemExit(f"timed out waiting for {text!r} in {paths}")


def stop(p: subprocess.Popen[bytes]) -> str:
    if p.poll() is None:
        p.terminate()
        try:
            p.wait(15)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
    if p.stderr is None:
        return ""
    return p.stderr.read().decode(errors="replace")


def wait_http(url: str, proc: subprocess.Popen[bytes], timeout: float = 180.0) -> None:
    import httpx

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            if httpx.get(url + "/api/v1/health", timeout=1).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        if proc.poll() is not None:
            raise SystemExit(f"API exited: {stop(proc)}")
        time.sleep(0.2)
    raise SystemExit("API did not start")


def warm_up(base: str, machines: list[tuple[int, int, str]], n: int) -> None:
    """A few empty batches on fresh connections, so every worker has built its routes
    (FastAPI builds them on first use) and prepared its statements before timing."""
    import httpx

    for i in range(n):
        token = machines[i % len(machines)][2]
        with httpx.Client(base_url=base) as c:
            r = c.post(
                "/api/v1/telemetry",
                json={"records": []},
                headers={"Authorization": f"Bearer {token}"},
            )
            r.raise_for_status()


# HTTP --------------------------------------------------------------------------------
class LeanHttp:
    """Keep-alive HTTP/1.1 POSTs over raw asyncio streams.

    The load generator shares the 2 cores with the server under test; httpx cost
    ~3x more CPU per request, which the server then did not get.
    """

    def __init__(self, base: str, connections: int) -> None:
        u = base.split("//", 1)[1]
        self.host, _, port = u.partition(":")
        self.port = int(port)
        self.n = connections
        self.pool: asyncio.Queue[tuple[asyncio.StreamReader, asyncio.StreamWriter]] = (
            asyncio.Queue()
        )

    async def __aenter__(self) -> LeanHttp:
        for _ in range(self.n):
            self.pool.put_nowait(await asyncio.open_connection(self.host, self.port))
        return self

    async def __aexit__(self, *exc: object) -> None:
        while not self.pool.empty():
            _, w = self.pool.get_nowait()
            w.close()

    async def post(self, path: str, body: str, token: str) -> tuple[int, bytes]:
        data = body.encode()
        head = (
            f"POST {path} HTTP/1.1\r\nHost: {self.host}\r\nAuthorization: Bearer {token}\r\n"
            f"Content-Type: application/json\r\nContent-Length: {len(data)}\r\n\r\n"
        ).encode()
        r, w = await self.pool.get()
        try:
            w.write(head + data)
            await w.drain()
            status_line = await r.readline()
            if not status_line:  # the server closed the idle keep-alive connection
                w.close()  # (--realtime, uploads further apart than its timeout): again,
                r, w = await asyncio.open_connection(self.host, self.port)  # on a new one
                w.write(head + data)  # (ingest deduplicates a batch stored twice)
                await w.drain()
                status_line = await r.readline()
            status = int(status_line.split()[1])
            length = 0
            while True:
                line = await r.readline()
                if line in (b"\r\n", b""):
                    break
                name, _, value = line.partition(b":")
                if name.strip().lower() == b"content-length":
                    length = int(value)
            payload = await r.readexactly(length)
        except BaseException:
            w.close()
            r, w = await asyncio.open_connection(self.host, self.port)
            raise
        finally:
            self.pool.put_nowait((r, w))
        return status, payload


async def drive_http(
    base: str, fleet: Fleet, batch: int, concurrency: int, realtime: bool, send_every: float
) -> tuple[float, list[float], int]:
    latencies: list[float] = []
    stored = 0
    sem = asyncio.Semaphore(concurrency)
    async with LeanHttp(base, concurrency) as client:
        start = time.time()

        async def machine(k: int) -> None:
            nonlocal stored
            token = fleet.machines[k][2]
            seq = 1
            while seq <= fleet.n:
                if realtime:
                    due = start + (seq - 1 + batch) / fleet.hz
                    await asyncio.sleep(
                        max(0.0, min(due, start + seq / fleet.hz + send_every) - time.time())
                    )
                    produced = int((time.time() - start) * fleet.hz)
                    count = max(1, min(batch, produced - seq + 1, fleet.n - seq + 1))
                else:
                    count = min(batch, fleet.n - seq + 1)
                async with sem:
                    t_now = time.time()
                    if realtime:
                        times = [start + (seq + i) / fleet.hz for i in range(count)]
                    else:
                        times = [t_now - (count - 1 - i) * 1e-6 for i in range(count)]
                    body = fleet.body(k, seq, times)
                    while True:
                        status, payload = await client.post("/api/v1/telemetry", body, token)
                        if status == 200:
                            break
                        print(f"HTTP {status}: {payload[:200]!r}", file=sys.stderr)
                        await asyncio.sleep(0.5)
                    ack = json.loads(payload)
                    t_ack = time.time()
                assert ack["acked_seq"] == seq + count - 1, ack
                stored += ack["stored"]
                latencies.extend(t_ack - tt for tt in times)
                seq += count

        await asyncio.gather(*(machine(k) for k in range(len(fleet.machines))))
        elapsed = time.time() - start
    return elapsed, latencies, stored


def thin_records(
    fleet: Fleet, k: int, t_now: float
) -> tuple[list[dict[str, Any]], list[dict[str, Any]], list[float]]:
    """Machine k's same drive as the thin profile produces it (fieldrx_edge.uplink.thin):
    every 10th fix as its 1 Hz track (no cell: the cell records count the cells), and one
    cell record per cell left (the bench's cells last 3 s); stamped ``t_now`` like the full
    profile's records (a backlog being replayed). Also each cell record's time into the
    drive (s) when its cell was left (``--realtime``)."""
    mid, jid, _ = fleet.machines[k]
    full = fleet.records(k, 1, fleet.n, t_now)
    step = max(1, int(round(fleet.hz)))
    track = []
    for i, r in enumerate(full[::step], start=1):
        track.append({**r, "seq": i, "cell_seq": None, "fix_period_s": step / fleet.hz})
    cells: dict[int, list[dict[str, Any]]] = {}
    for r in full:
        cells.setdefault(r["cell_seq"], []).append(r)
    cell_recs, left_at, fixes = [], [], 0
    for i, (cell, rs) in enumerate(cells.items(), start=1):
        n = len(rs)
        fixes += n
        left_at.append(fixes / fleet.hz)
        cell_recs.append(
            {
                "machine_id": mid, "seq": i, "job_id": jid, "cell_seq": cell,
                "t_entry": rs[0]["t"], "t_exit": rs[-1]["t"], "n_fixes": n,
                "worked_s": n / fleet.hz, "mass_g": 300.0 * 2.3 * 1.7 * n / fleet.hz / 10.0,
                "driven_m": 1.7 * n / fleet.hz, "mean_speed_m_s": 1.7,
                "mean_target_rate_kg_ha": 300.0, "mean_applied_rate_kg_ha": 300.0,
                "flags": [],
            }
        )  # fmt: skip
    return track, cell_recs, left_at


def lane_body(k: int, kind: str, recs: list[dict[str, Any]]) -> str:
    """One batch of machine k's thin ``kind`` lane ("track" or "cells") as the agent sends
    it."""
    head = (
        f'"format":2,"stream":"thin{k}"'
        if kind == "track"
        else f'"format":3,"kind":"cells","stream":"cells{k}"'
    )
    return f'{{{head},"stream_start":1,"records":{json.dumps(recs, separators=(",", ":"))}}}'


def thin_lanes(fleet: Fleet, k: int, batch: int, t_now: float) -> list[list[str]]:
    """``thin_records`` in batches of ``batch`` (the agent's two queues): the track lane's
    batch bodies, then the cell lane's."""
    track, cell_recs, _ = thin_records(fleet, k, t_now)
    return [
        [lane_body(k, kind, recs[i : i + batch]) for i in range(0, len(recs), batch)]
        for kind, recs in (("track", track), ("cells", cell_recs))
    ]


def multi_body(parts: list[str]) -> str:
    """The two queues' pending batches in one request (protocol.MULTI_KIND) when both have
    records, else the one batch alone, as fieldrx_edge.uplink.http.HttpSender sends them."""
    if len(parts) == 1:
        return parts[0]
    return '{"format":3,"kind":"batches","batches":[' + ",".join(parts) + "]}"


def thin_bodies(fleet: Fleet, k: int, batch: int, t_now: float) -> list[str]:
    """``thin_lanes`` as the HTTP sender sends them (``multi_body``)."""
    lanes = thin_lanes(fleet, k, batch, t_now)
    return [
        multi_body([lane[i] for lane in lanes if i < len(lane)])
        for i in range(max(map(len, lanes)))
    ]


def thin_realtime_bodies(
    fleet: Fleet, k: int, batch: int, send_every: float
) -> list[tuple[float, str]]:
    """``--realtime``: what machine k's thin agent sends every ``send_every`` s while it
    drives (the track records of the last period, the cells left in it; at most ``batch``
    per lane per request), each with its time into the drive."""
    track, cell_recs, left_at = thin_records(fleet, k, time.time())
    out: list[tuple[float, str]] = []
    ti = ci = 0
    t = 0.0
    while ti < len(track) or ci < len(cell_recs):
        t += send_every
        tj = min(len(track), int(t + 1e-9), ti + batch)  # 1 Hz: record i at i s
        cj = ci
        while cj < len(cell_recs) and cj - ci < batch and left_at[cj] <= t + 1e-9:
            cj += 1
        parts = []
        if tj > ti:
            parts.append(lane_body(k, "track", track[ti:tj]))
        if cj > ci:
            parts.append(lane_body(k, "cells", cell_recs[ci:cj]))
        if parts:
            out.append((t, multi_body(parts)))
        ti, ci = tj, cj
    return out


async def drive_http_thin(
    base: str, fleet: Fleet, batch: int, concurrency: int, realtime: bool, send_every: float
) -> tuple[float, int, int]:
    """The same machine-hours as the thin profile sends them (``thin_bodies``, or with
    ``realtime`` ``thin_realtime_bodies`` at their times): elapsed s, records sent,
    records stored."""
    sem = asyncio.Semaphore(concurrency)
    sent = stored = 0
    # rendered before the connections open, as the full profile's bodies are: rendering a
    # long drive's bodies inside the window took longer than the server's keep-alive
    # timeout at --seconds 600, and the idle connections were closed under the client
    now = time.time()
    bodies = [
        thin_realtime_bodies(fleet, k, batch, send_every)
        if realtime
        else [(0.0, b) for b in thin_bodies(fleet, k, batch, now)]
        for k in range(len(fleet.machines))
    ]
    async with LeanHttp(base, concurrency) as client:
        start = time.time()

        async def machine(k: int) -> None:
            nonlocal sent, stored
            token = fleet.machines[k][2]
            for due, body in bodies[k]:
                await asyncio.sleep(max(0.0, start + due - time.time()))
                async with sem:
                    while True:
                        status, payload = await client.post("/api/v1/telemetry", body, token)
                        if status == 200:
                            break
                        print(f"HTTP {status}: {payload[:200]!r}", file=sys.stderr)
                        await asyncio.sleep(0.5)
                answer = json.loads(payload)
                for ack in answer.get("acks", [answer]):
                    assert not ack["rejected"], ack["rejected"][:3]
                    stored += ack["stored"]
                sent += body.count('"machine_id"')

        await asyncio.gather(*(machine(k) for k in range(len(fleet.machines))))
        elapsed = time.time() - start
    return elapsed, sent, stored


# MQTT --------------------------------------------------------------------------------
def mqtt_clients(
    port: int, fleet: Fleet, max_inflight: int, on_message: Callable[..., None]
) -> dict[int, Any]:
    """One connected client per machine, logged in as itself (machine-<id>, its device
    token), as agents do: the broker lets it publish only its own telemetry and read only
    its own acks (subscribed, ``on_message``)."""
    import paho.mqtt.client as mqtt
    from fieldrx_edge.protocol import ack_topic, mqtt_client_id, mqtt_username

    clients: dict[int, mqtt.Client] = {}
    for mid, _, token in fleet.machines:
        c = mqtt.Client(
            mqtt.CallbackAPIVersion.VERSION2, client_id=mqtt_client_id(mid), protocol=mqtt.MQTTv5
        )
        c.username_pw_set(mqtt_username(mid), token)
        c.max_inflight_messages_set(max_inflight)
        c.max_queued_messages_set(0)
        c.on_message = on_message
        c.connect("127.0.0.1", port)
        c.subscribe(ack_topic(mid), qos=1)
        c.loop_start()
        clients[mid] = c
    time.sleep(0.5)
    return clients


def drive_mqtt_thin(port: int, fleet: Fleet, batch: int) -> tuple[float, int, int]:
    """The thin profile over MQTT: each machine publishes its two lanes' batches
    (``thin_lanes``; one batch per message, as fieldrx_edge.uplink.mqtt sends them) and
    waits for the acks of both streams; elapsed s, records sent, records stored."""
    import paho.mqtt.client as mqtt
    from fieldrx_edge.protocol import telemetry_topic

    now = time.time()
    lanes = [thin_lanes(fleet, k, batch, now) for k in range(len(fleet.machines))]
    want = {
        (mid, f"{kind}{k}"): sum(body.count('"machine_id"') for body in lane)
        for k, (mid, _, _) in enumerate(fleet.machines)
        for kind, lane in zip(("thin", "cells"), lanes[k], strict=True)
    }
    acked = dict.fromkeys(want, 0)
    stored = 0
    cv = threading.Condition()

    def on_message(client, userdata, msg) -> None:  # noqa: ANN001
        nonlocal stored
        ack = json.loads(msg.payload)
        assert not ack.get("error") and not ack["rejected"], ack
        with cv:
            stored += ack["stored"]
            key = (ack["machine_id"], ack["stream"])
            acked[key] = max(acked[key], ack["acked_seq"])
            cv.notify_all()

    clients = mqtt_clients(port, fleet, 1000, on_message)
    start = time.time()
    for k, (mid, _, _) in enumerate(fleet.machines):
        for lane in lanes[k]:
            for body in lane:
                info = clients[mid].publish(telemetry_topic(mid), body, qos=1)
                if info.rc != mqtt.MQTT_ERR_SUCCESS:
                    raise SystemExit(f"publish failed rc={info.rc}")
    with cv:
        ok = cv.wait_for(lambda: acked == want, timeout=300)
    elapsed = time.time() - start
    for c in clients.values():
        c.disconnect()
        c.loop_stop()
    if not ok:
        print(f"thin: timed out waiting for acks: {sum(acked.values())} / {sum(want.values())}",
              file=sys.stderr)  # fmt: skip
    return elapsed, sum(want.values()), stored


def drive_mqtt(
    port: int,
    fleet: Fleet,
    batch: int,
    max_inflight: int,
    realtime: bool,
    send_every: float = 0.0,
) -> tuple[float, list[float], int]:
    """Every machine logs in as itself (``mqtt_clients``); with ``realtime`` a machine
    publishes what it produced once per ``send_every`` s (a full batch at once), as the
    agent's sender does with its upload period."""
    import paho.mqtt.client as mqtt
    from fieldrx_edge.protocol import telemetry_topic

    n_m = len(fleet.machines)
    acked = {m[0]: 0 for m in fleet.machines}
    index = {m[0]: k for k, m in enumerate(fleet.machines)}
    # per machine: record times by seq, to turn ack arrival into per-record latency
    tstamps = [np.zeros(fleet.n + 1) for _ in range(n_m)]
    latencies: list[float] = []
    stored = 0
    cv = threading.Condition()

    def on_message(client, userdata, msg) -> None:  # noqa: ANN001
        nonlocal stored
        ack = json.loads(msg.payload)
        t_ack = time.time()
        mid = ack["machine_id"]
        with cv:
            stored += ack["stored"]
            a = ack["acked_seq"]
            old = acked[mid]
            if a > old:
                ts = tstamps[index[mid]][old + 1 : a + 1]
                latencies.extend((t_ack - ts).tolist())
                acked[mid] = a
            cv.notify_all()

    clients = mqtt_clients(port, fleet, max_inflight, on_message)
    sent = [1] * n_m
    start = time.time()
    # each machine keeps at most `window` unacked batches (the agent's in-flight cap)
    window = 4
    last = [-math.inf] * n_m  # realtime: each machine's previous upload
    while True:
        progressed = False
        all_done = True
        for k, (mid, _, _) in enumerate(fleet.machines):
            seq = sent[k]
            if seq > fleet.n:
                continue
            all_done = False
            with cv:
                if seq - 1 - acked[mid] >= window * batch:
                    continue
            count = min(batch, fleet.n - seq + 1)
            if realtime:
                produced = int((time.time() - start) * fleet.hz)
                count = min(count, produced - seq + 1)
                if count <= 0 or (count < batch and time.time() - last[k] < send_every):
                    continue
                last[k] = time.time()
            t_now = time.time()
            if realtime:
                times = [start + (seq + i) / fleet.hz for i in range(count)]
            else:
                times = [t_now - (count - 1 - i) * 1e-6 for i in range(count)]
            tstamps[k][seq : seq + count] = times
            # the pre-rendered JSON, as the HTTP driver sends it (Fleet.prepare)
            info = clients[mid].publish(telemetry_topic(mid), fleet.body(k, seq, times), qos=1)
            if info.rc != mqtt.MQTT_ERR_SUCCESS:
                raise SystemExit(f"publish failed rc={info.rc}")
            sent[k] = seq + count
            progressed = True
        if all_done:
            break
        if not progressed:
            with cv:
                cv.wait(0.01)
    with cv:
        ok = cv.wait_for(lambda: all(v == fleet.n for v in acked.values()), timeout=300)
    elapsed = time.time() - start
    for c in clients.values():
        c.disconnect()
        c.loop_stop()
    if not ok:
        print(
            f"timed out waiting for acks: {sum(acked.values())} / {fleet.n * n_m}", file=sys.stderr
        )
    return elapsed, latencies, stored


def start_broker() -> ProjectBroker:
    """The project's broker from the shipped deploy/mosquitto.conf (authentication and
    per-machine ACLs included) on a free port; MQTT_URL points at it, so the device
    tokens seed() issues get their broker credentials there."""
    from fieldrx.settings import get_settings

    broker = ProjectBroker()
    os.environ["MQTT_URL"] = broker.url
    get_settings.cache_clear()
    return broker


def cpu_seconds(db_name: str) -> dict[int, tuple[str, float]]:
    """CPU time (user+sys) so far per process (pid -> (category, s)) of this client
    ("client"), its child processes (API servers, workers, broker: "server") and the
    PostgreSQL backends serving the bench database ("postgres"); other processes on the
    machine are not listed. ``cpu_used`` takes the difference of two samples."""
    tick = os.sysconf("SC_CLK_TCK")
    me = os.getpid()
    procs: dict[int, tuple[int, float, str]] = {}
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_text()
            cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()
        procs[int(d.name)] = (int(fields[1]), (int(fields[11]) + int(fields[12])) / tick, cmd)
    out: dict[int, tuple[str, float]] = {}
    for pid, (ppid, cpu, cmd) in procs.items():
        if pid == me:
            out[pid] = ("client", cpu)
        elif cmd.startswith("postgres:") and f" {db_name} " in cmd:
            out[pid] = ("postgres", cpu)
        else:
            p = ppid
            while p > 1 and p in procs:
                if p == me:
                    out[pid] = ("server", cpu)
                    break
                p = procs[p][0]
    return out


def cpu_used(a: dict[int, tuple[str, float]], b: dict[int, tuple[str, float]]) -> dict[str, float]:
    """CPU s per category between two ``cpu_seconds`` samples, process by process. A process
    gone by ``b`` counts nothing: subtracting its whole CPU so far (as a difference of
    totals did) made the window's figure depend on whether a finished connection's
    backend, e.g. the VACUUM before the thin window, had exited before or after ``a``."""
    out = {"postgres": 0.0, "server": 0.0, "client": 0.0}
    for pid, (kind, cpu) in b.items():
        before = a.get(pid)
        out[kind] += cpu - (before[1] if before is not None and before[0] == kind else 0.0)
    return out


def thin_phase(
    url: str,
    db_name: str,
    used: dict[str, float],
    machine_h: float,
    server: str,
    drive: Callable[[], tuple[float, int, int]],
) -> dict[str, Any]:
    """The same machine-hours with the thin profile, sent by ``drive``: the
    server's CPU (``server`` processes and PostgreSQL backends) per machine-hour, full
    (``used``, the full phase's window) against thin, and their ratios."""
    import psycopg
    from fieldrx.db.session import raw_dsn

    # the maintenance the full phase left behind (autovacuum / autoanalyze of its rows),
    # outside both windows: else it lands in the thin window
    with psycopg.connect(raw_dsn(url), autocommit=True) as conn:
        conn.execute("VACUUM (ANALYZE)")
    t0 = cpu_seconds(db_name)
    t_el, t_sent, t_stored = drive()
    used_thin = cpu_used(t0, cpu_seconds(db_name))
    srv_full = used["server"] + used["postgres"]
    srv_thin = used_thin["server"] + used_thin["postgres"]
    api_full, api_thin = used["server"], used_thin["server"]
    thin = {
        "machine_hours": round(machine_h, 3),
        "records": t_sent,
        "stored": t_stored,
        "elapsed_s": round(t_el, 3),
        "server_cpu_s_per_machine_hour_full": round(srv_full / machine_h, 3),
        "server_cpu_s_per_machine_hour_thin": round(srv_thin / machine_h, 3),
        "cpu_ratio_full_to_thin": round(srv_full / max(srv_thin, 1e-9), 2),
        "api_cpu_ratio_full_to_thin": round(api_full / max(api_thin, 1e-9), 2),
        "postgres_cpu_ratio_full_to_thin": round(
            (srv_full - api_full) / max(srv_thin - api_thin, 1e-9), 2
        ),
    }
    print(
        f"thin profile: {t_sent} records for the same {machine_h:.2f} machine-hours,"
        f" server CPU ({server} + PostgreSQL) {thin['server_cpu_s_per_machine_hour_full']}"
        f" s/machine-hour full vs {thin['server_cpu_s_per_machine_hour_thin']} thin:"
        f" {thin['cpu_ratio_full_to_thin']} x lower ({server} alone"
        f" {thin['api_cpu_ratio_full_to_thin']} x, PostgreSQL alone"
        f" {thin['postgres_cpu_ratio_full_to_thin']} x)"
    )
    return thin


def _worker_totals(logs: list[Path]) -> list[int]:
    """Records each stopped worker says it stored (-1: no totals line); a log with a
    traceback (or every log with BENCH_LOGS set) is printed."""
    out = []
    for log in logs:
        text = log.read_text(errors="replace")
        m = re.search(r"records=(\d+), stored=(\d+), duplicates=(\d+)", text)
        out.append(int(m.group(2)) if m else -1)
        if "Traceback" in text or os.environ.get("BENCH_LOGS"):
            print(text[-3000:], file=sys.stderr)
    return out


# main --------------------------------------------------------------------------------
def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--machines", type=int, default=200)
    ap.add_argument("--hz", type=float, default=10.0)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--transport", choices=("http", "mqtt"), default="http")
    ap.add_argument(
        "--workers",
        type=int,
        default=None,
        help="uvicorn workers (http, default 2) or ingest workers (mqtt, default 2)",
    )
    ap.add_argument(
        "--batch",
        type=int,
        default=None,
        help="records per batch (default: http 500, mqtt 200, as the edge agent)",
    )
    ap.add_argument("--concurrency", type=int, default=8, help="HTTP requests in flight")
    ap.add_argument("--batch-ms", type=int, default=100, help="MQTT worker batching window")
    ap.add_argument(
        "--db-connections",
        type=int,
        default=0,
        help="database connections per MQTT ingest worker (default: the worker's default)",
    )
    ap.add_argument(
        "--realtime", action="store_true", help="produce at --hz instead of replaying a backlog"
    )
    ap.add_argument(
        "--send-every",
        type=float,
        default=UPLOAD_PERIOD_S["full"],
        help="realtime: seconds between uploads (default: the agent's full profile's period)",
    )
    ap.add_argument(
        "--thin-send-every",
        type=float,
        default=UPLOAD_PERIOD_S["thin"],
        help="realtime: seconds between the thin phase's uploads (default: the agent's thin"
        " profile's period, fieldrx_edge.protocol.UPLOAD_PERIOD_S)",
    )
    ap.add_argument("--keep-db", action="store_true")
    ap.add_argument(
        "--database-url",
        default=None,
        help="use this empty, migrated database instead of a throw-away one (a Citus"
        " coordinator's after `fieldrx migrate` and `fieldrx distribute`: a new database"
        " there needs the extensions and the worker nodes first); it is kept",
    )
    ap.add_argument(
        "--thin",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="also send the same machine-hours with the thin profile (server CPU ratio)",
    )
    args = ap.parse_args()
    workers = args.workers or 2
    batch = args.batch or (500 if args.transport == "http" else 200)

    from fieldrx.db.bootstrap import drop_database

    url = args.database_url or make_db()
    tmp = Path(tempfile.mkdtemp(prefix="fieldrx-bench-"))
    procs: list[subprocess.Popen[bytes]] = []
    worker_records: list[int] = []
    broker: ProjectBroker | None = None
    try:
        if args.transport == "mqtt":
            broker = start_broker()
        else:  # HTTP only: device tokens need no broker credential
            os.environ["FIELDRX_MQTT_CREDENTIALS"] = "off"
        machines = seed(url, args.machines)
        db_name = url.rsplit("/", 1)[1]
        fleet = Fleet(machines, args.hz, args.seconds)
        total = fleet.n * len(machines)
        print(
            f"{len(machines)} machines x {fleet.n} records = {total} records,"
            f" transport {args.transport}, batch {batch}"
        )
        raw = raw_copy_baseline(url, fleet)
        fleet.prepare()
        print(f"raw COPY BINARY baseline: {raw:,.0f} records/s")
        env = {"DATABASE_URL": url, "FIELDRX_HEARTBEAT_TIMEOUT_S": "3600"}
        machine_h = len(machines) * args.seconds / 3600.0
        thin: dict[str, Any] = {}
        if args.transport == "http":
            port = free_port()
            # as production starts it (scripts/run.sh, docker-compose.yml: ``fieldrx serve``,
            # uvicorn's event loop and HTTP parser "auto": uvloop and httptools, both in
            # requirements.lock); --quiet: no access log line per request
            api = start(
                [
                    str(BIN / "fieldrx"),
                    "serve",
                    "--host",
                    "127.0.0.1",
                    "--port",
                    str(port),
                    "--workers",
                    str(workers),
                    "--quiet",
                ],
                env,
            )
            procs.append(api)
            base = f"http://127.0.0.1:{port}"
            wait_http(base, api)
            warm_up(base, machines, 8 * workers)
            cpu0 = cpu_seconds(db_name)
            elapsed, lat, stored = asyncio.run(
                drive_http(base, fleet, batch, args.concurrency, args.realtime, args.send_every)
            )
        else:
            assert broker is not None
            port = broker.port
            env["MQTT_URL"] = broker.url
            group = "bench"
            logs = [tmp / f"worker{i}.log" for i in range(workers)]
            lanes = ["--db-connections", str(args.db_connections)] if args.db_connections else []
            cmd = [
                str(BIN / "fieldrx"),
                "worker",
                "--role",
                "ingest",
                "--group",
                group,
                "--batch-ms",
                str(args.batch_ms),
                "--mqtt-url",
                f"mqtt://127.0.0.1:{port}",
                *lanes,
            ]
            for log in logs:
                procs.append(start(cmd, env, log))  # each at once: the finally stops it
            wait_log(logs, "subscribed to")
            cpu0 = cpu_seconds(db_name)
            elapsed, lat, stored = drive_mqtt(
                port, fleet, batch, 1000, args.realtime, args.send_every
            )
            cpu1 = cpu_seconds(db_name)
            used = cpu_used(cpu0, cpu1)
            if args.thin:
                thin = thin_phase(
                    url, db_name, used, machine_h, "workers + broker",
                    lambda: drive_mqtt_thin(port, fleet, batch),
                )  # fmt: skip
            for w in procs:
                stop(w)  # the workers log their totals when they stop
            worker_records += _worker_totals(logs)
            print(f"records stored per worker: {worker_records}")
        if args.transport == "http":
            cpu1 = cpu_seconds(db_name)
            used = cpu_used(cpu0, cpu1)
        cpu_us = {k: round(v / total * 1e6, 1) for k, v in used.items()}
        print(f"CPU per record (us): {cpu_us}")
        if args.transport == "http" and args.thin:
            thin = thin_phase(
                url, db_name, used, machine_h, "API",
                lambda: asyncio.run(
                    drive_http_thin(
                        base, fleet, batch, args.concurrency, args.realtime,
                        args.thin_send_every,
                    )  # fmt: skip
                ),
            )  # fmt: skip
        import psycopg
        from fieldrx.db.session import raw_dsn

        with psycopg.connect(raw_dsn(url)) as conn:
            rows, distinct = conn.execute(
                "SELECT count(*), count(DISTINCT (machine_id, stream, seq)) FROM telemetry"
                " WHERE stream NOT LIKE 'thin%'"
            ).fetchone()
            if thin:
                t_rows, t_distinct = conn.execute(
                    "SELECT (SELECT count(*) FROM telemetry WHERE stream LIKE 'thin%')"
                    " + (SELECT count(*) FROM job_cell_records),"
                    " (SELECT count(DISTINCT (machine_id, stream, seq)) FROM telemetry"
                    "  WHERE stream LIKE 'thin%')"
                    " + (SELECT count(DISTINCT (machine_id, stream, seq)) FROM job_cell_records)"
                ).fetchone()
                thin["lost"] = int(thin["records"] - t_distinct)
                thin["duplicated"] = int(t_rows - t_distinct + max(0, thin["stored"] - t_distinct))
            acked = conn.execute(
                "SELECT coalesce(sum(acked_seq), 0) FROM telemetry_streams"
                " WHERE stream NOT LIKE 'thin%'"
            ).fetchone()[0]
            # per-cell aggregates: the full phase's fixes plus the thin phase's cell records'
            cells = conn.execute(
                "SELECT coalesce(sum(n_records), 0) FROM job_cells_applied"
            ).fetchone()[0] - (total if thin else 0)
        lost = total - distinct
        duplicated = (rows - distinct) + max(0, stored - distinct)
        rps = total / elapsed
        lat_a = np.asarray(lat) if lat else np.asarray([float("nan")])
        out = {
            "transport": args.transport,
            "machines": len(machines),
            "hz": args.hz,
            "seconds": args.seconds,
            "batch": batch,
            "workers": workers,
            "realtime": args.realtime,
            "records": total,
            "elapsed_s": round(elapsed, 3),
            "records_per_s": round(rps, 1),
            "raw_copy_records_per_s": round(raw, 1),
            "ratio_to_copy": round(rps / raw, 3),
            "p50_latency_s": round(float(np.percentile(lat_a, 50)), 4),
            "p99_latency_s": round(float(np.percentile(lat_a, 99)), 4),
            "lost": int(lost),
            "duplicated": int(duplicated),
            "acked_total": int(acked),
            "cell_records": int(cells),
            "thin": thin,
            "cpu_us_per_record": cpu_us,
            "worker_stored": worker_records,
        }
        print(
            f"{args.transport}: {rps:,.0f} records/s sustained ({total} in {elapsed:.2f} s), "
            f"{rps / raw:.2f} x raw COPY; latency p50 {out['p50_latency_s']} s"
            f" p99 {out['p99_latency_s']} s; "
            f"lost {lost}, duplicated {duplicated}"
        )
        if thin:
            print(
                f"thin: lost {thin['lost']}, duplicated {thin['duplicated']};"
                f" CPU per machine-hour {thin['cpu_ratio_full_to_thin']} x lower"
            )
        print(json.dumps(out))
        ok = lost == 0 and duplicated == 0
        if thin:
            ok = ok and thin["lost"] == 0 and thin["duplicated"] == 0
        return 0 if ok else 1
    finally:
        for p in reversed(procs):
            err = stop(p)
            if "Traceback" in err or "WARNING" in err or os.environ.get("BENCH_LOGS"):
                print(err[-3000:], file=sys.stderr)
        shutil.rmtree(tmp, ignore_errors=True)
        if broker is not None:
            broker.close()
        if not (args.keep_db or args.database_url):
            drop_database(url)
            citus_cluster.drop(url)


if __name__ == "__main__":
    sys.exit(main())
