"""MQTT ingest worker: an MQTT 5 shared subscription, batched into ingest transactions.

Several workers subscribe to ``$share/<group>/fieldrx/machines/+/telemetry``;
the broker gives each message to one of them, so they split the load. A
message is acknowledged to the broker (manual PUBACK) only after its records
are committed, so a worker that dies loses nothing: the broker redelivers, and
ingest deduplicates by (machine, stream, seq). Messages that arrive within
``batch_ms`` (or are already waiting: a busy worker does not wait out the window) are
grouped per machine and stream into one batch, and a round's batches of several machines
into one transaction (``multibatch.store_free``: one lock statement, one COPY, one COMMIT
instead of each batch's own; a machine another worker's transaction holds is held over to
the next round rather than waited for); the ``TelemetryAck`` (naming the stream) goes back
on ``ack_topic(machine_id)`` after that commit. If the shared transaction fails, each batch
is stored on its own; one the database refuses gets an ack with ``error`` (as a thin HTTP
request's batch), so it neither blocks nor takes down another machine's.
A record the protocol forbids (NaN, a far-future time) is rejected alone in
the ack, never a reason to drop the message unanswered: an agent that gets no
ack resends forever.

Security: the worker logs in as ``fieldrx-worker`` (``fieldrx.auth.mqtt``); the
broker lets only machine N publish on machine N's telemetry topic, so the machine
id taken from the topic is the sender's. Defence in depth: ingest rejects every
record whose ``machine_id`` is not the topic's.

Telemetry partitions: every ``maintenance_s`` (FIELDRX_TELEMETRY_MAINTENANCE_S, from
start) a worker runs ``fleet.partitions.maintain`` (premake days, move late records out
of the default partition, drop days past FIELDRX_TELEMETRY_RETENTION_DAYS); workers take
turns, one run at a time.

Sessions: each worker holds a *slot* (the lowest free one per node, broker and
group, kept by a lock file in FIELDRX_WORKER_SLOT_DIR) and connects as
``fieldrx-worker-<group>-<node>-<slot>`` (node: FIELDRX_WORKER_NODE, default the
host name) with a persistent session (expiry FIELDRX_WORKER_SESSION_EXPIRY_S, default 1 h).
A killed worker's unacknowledged and queued messages wait in its session, and the
restarted worker takes the same slot, so the same session: nothing is lost, and a
dead member holds messages only until its slot is back (not for the whole expiry).

Lanes: a worker holds ``db_connections`` database connections (FIELDRX_WORKER_DB_CONNECTIONS),
each with its own thread and inbox; a message goes to lane ``machine_id % lanes``, so one
machine's messages stay in order on one connection while other machines' batches commit
at the same time. Why: a batch's thread waits on PostgreSQL (COPY, COMMIT's WAL flush)
about two thirds of the time (py-spy); with one connection that wait was the
worker's throughput. Every guarantee is per lane as before: a message is acked after the
commit that stored it, on the connection that committed it.
"""

from __future__ import annotations

import fcntl
import logging
import os
import queue
import socket
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import paho.mqtt.client as mqtt
import psycopg
from fieldrx_edge.protocol import ack_topic
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties

from fieldrx.auth.mqtt import WORKER_USER, Broker
from fieldrx.db.session import raw_dsn
from fieldrx.fleet.alerts import check_no_data
from fieldrx.fleet.db import connect
from fieldrx.fleet.ingest.model import Batch, IngestError, IngestResult
from fieldrx.fleet.ingest.parse import parse_batch
from fieldrx.fleet.multibatch import (
    error_ack,
    reason_of,
    refused,
    store,
    store_free,
    store_together,
    work_of,
)
from fieldrx.fleet.partitions import maintain
from fieldrx.fleet.status import sweep_offline

log = logging.getLogger(__name__)

TOPIC = "fieldrx/machines/+/telemetry"
BUSY_MESSAGES = 64  # this many waiting: process now, do not wait out the batching window


@dataclass
class WorkerStats:
    """Counters of one lane (``IngestWorker.stats`` sums the lanes)."""

    messages: int = 0
    records: int = 0
    stored: int = 0
    duplicates: int = 0
    rejected: int = 0
    batches: int = 0
    errors: int = 0
    started: float = field(default_factory=time.monotonic)


def _machine_of(topic: str) -> int | None:
    parts = topic.split("/")
    if len(parts) == 4 and parts[0] == "fieldrx" and parts[1] == "machines":
        try:
            return int(parts[2])
        except ValueError:
            return None
    return None


@dataclass(frozen=True)
class IngestOptions:
    """How an ingest worker runs (the FIELDRX_WORKER_* and telemetry settings; seconds).

    ``client_id`` None: fieldrx-worker-GROUP-NODE-SLOT, the lowest slot free on this node
    (``node`` default the host name, slots locked under ``slot_dir``, default the temp
    directory). ``maintenance_s`` 0: no telemetry partition maintenance."""

    group: str = "fieldrx"
    batch_ms: float = 100.0
    client_id: str | None = None
    heartbeat_timeout_s: float = 30.0
    no_data_every_s: float = 5.0
    session_expiry_s: int = 3600
    node: str = ""
    slot_dir: str = ""
    maintenance_s: float = 0.0
    retention_days: int = 0
    db_connections: int = 1


class IngestWorker:
    """One worker process's MQTT client and its batching loop."""

    def __init__(
        self, mqtt_url: str, dsn: str | None = None, opts: IngestOptions = IngestOptions()
    ) -> None:
        group, client_id, db_connections = opts.group, opts.client_id, opts.db_connections
        session_expiry_s = opts.session_expiry_s
        if db_connections < 1:
            raise ValueError(f"db_connections must be at least 1, got {db_connections}")
        self.broker = Broker.from_url(mqtt_url, WORKER_USER)
        self.host = self.broker.host
        self.port = self.broker.port
        self.dsn = dsn or raw_dsn()
        self.group = group
        self.batch_s = opts.batch_ms / 1000.0
        self.heartbeat_timeout_s = opts.heartbeat_timeout_s
        self.no_data_every_s = opts.no_data_every_s
        # telemetry partition maintenance (fleet.partitions) every maintenance_s, from start;
        # workers take turns (the first to hold the lock runs it, the others skip)
        self.maintenance_s = opts.maintenance_s
        self.retention_days = opts.retention_days
        # one inbox and one set of counters per lane (database connection), see the docstring
        self.inboxes: list[queue.Queue[mqtt.MQTTMessage]] = [
            queue.Queue() for _ in range(db_connections)
        ]
        self.lane_stats = [WorkerStats() for _ in range(db_connections)]
        self._lane_error: BaseException | None = None
        self.subscribed = threading.Event()
        self.session_expiry_s = session_expiry_s
        self.persistent = session_expiry_s > 0
        self._slot_lock: IO[str] | None = None
        if client_id is None:
            node = opts.node or socket.gethostname()
            slot_dir = Path(opts.slot_dir or tempfile.gettempdir()) / "fieldrx-worker-slots"
            slot = self._take_slot(slot_dir)
            client_id = f"fieldrx-worker-{group}-{node}-{slot}"
        self.client_id = client_id
        self.client = mqtt.Client(
            mqtt.CallbackAPIVersion.VERSION2,
            client_id=client_id,
            protocol=mqtt.MQTTv5,
            manual_ack=True,
        )
        self.client.on_connect = self._on_connect
        self.client.on_message = self._on_message
        self.client.on_subscribe = self._on_subscribe
        self.client.reconnect_delay_set(1, 10)  # paho takes whole seconds
        self.broker.configure(self.client)

    def _take_slot(self, d: Path) -> int:
        """The lowest slot no live worker of this node, broker and group holds; the lock
        file's flock lasts as long as this process, so a killed worker's slot is free for
        its replacement at once. Containers that share ``d`` (a volume) share the slots."""
        d.mkdir(parents=True, exist_ok=True)
        slot = 0
        while True:
            name = f"{self.host}-{self.port}-{self.group}-{slot}.lock".replace("/", "_")
            f = open(d / name, "a")  # noqa: SIM115 - held until the process ends
            try:
                fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                f.close()
                slot += 1
                continue
            self._slot_lock = f
            return slot

    # paho network thread ------------------------------------------------------------
    def _on_connect(self, client, userdata, flags, reason_code, properties) -> None:  # noqa: ANN001
        if reason_code.is_failure:
            log.warning("MQTT connect failed: %s", reason_code)
            return
        client.subscribe(f"$share/{self.group}/{TOPIC}", qos=1)

    def _on_subscribe(self, client, userdata, mid, reason_codes, properties) -> None:  # noqa: ANN001
        if any(rc.is_failure for rc in reason_codes):
            log.error(
                "subscription to $share/%s/%s refused: %s (is %s a worker user?)",
                self.group,
                TOPIC,
                reason_codes[0],
                self.broker.username,
            )
            return
        log.warning(
            "subscribed to $share/%s/%s as %s (session expiry %d s)",
            self.group,
            TOPIC,
            self.client_id,
            self.session_expiry_s,
        )
        self.subscribed.set()

    def _on_message(self, client, userdata, msg: mqtt.MQTTMessage) -> None:  # noqa: ANN001
        # a machine's messages always go to the same lane: its batches stay in order
        mid = _machine_of(msg.topic) or 0
        self.inboxes[mid % len(self.inboxes)].put(msg)

    @property
    def stats(self) -> WorkerStats:
        """The lanes' counters summed."""
        total = WorkerStats(started=self.lane_stats[0].started)
        for s in self.lane_stats:
            for name in ("messages", "records", "stored", "duplicates", "rejected", "batches"):
                setattr(total, name, getattr(total, name) + getattr(s, name))
            total.errors += s.errors
        return total

    # processing thread -------------------------------------------------------------
    def run(self, stop: threading.Event) -> WorkerStats:
        # the slot's stable client id resumes its session (unacked and queued messages)
        props = Properties(PacketTypes.CONNECT)
        props.SessionExpiryInterval = self.session_expiry_s
        self.client.connect(
            self.host, self.port, keepalive=30, clean_start=not self.persistent, properties=props
        )
        self.client.loop_start()
        conn = connect(self.dsn)
        halt = threading.Event()  # stop, or a lane failed: every lane ends
        lanes = [
            threading.Thread(target=self._lane, args=(i, halt), name=f"ingest-lane-{i}")
            for i in range(len(self.inboxes))
        ]
        for t in lanes:
            t.start()
        last_check = 0.0
        last_maintenance = -float("inf")
        try:
            while not stop.is_set() and not halt.is_set():
                stop.wait(0.2)
                now = time.monotonic()
                if now - last_check >= self.no_data_every_s:
                    last_check = now
                    try:
                        check_no_data(conn, self.heartbeat_timeout_s)
                        sweep_offline(conn, self.heartbeat_timeout_s)
                        self._beat()
                    except psycopg.Error as exc:
                        log.warning("no-data check failed: %s", exc)
                        conn = self._reconnect(conn)
                if self.maintenance_s > 0 and now - last_maintenance >= self.maintenance_s:
                    last_maintenance = now
                    conn = self._maintain(conn)
        finally:
            halt.set()
            for t in lanes:
                t.join()
            self.client.loop_stop()
            self.client.disconnect()
            conn.close()
        if self._lane_error is not None:
            raise RuntimeError("an ingest lane failed") from self._lane_error
        return self.stats

    def _lane(self, i: int, halt: threading.Event) -> None:
        """Lane ``i``: its inbox's messages, batched into transactions on its connection."""
        inbox, stats = self.inboxes[i], self.lane_stats[i]
        try:
            conn = connect(self.dsn)
            held: dict[tuple[int, str], _Batch] = {}  # busy machines' batches (store_free)
            try:
                while not halt.is_set():
                    try:
                        first = inbox.get(timeout=0.0 if held else 0.2)
                    except queue.Empty:
                        if held:  # nothing new: store them now, waiting for their locks
                            conn = self._process(conn, [], stats, held)
                        continue
                    conn = self._process(conn, self._gather(inbox, first), stats, held)
            finally:
                conn.close()
        except BaseException as exc:  # the worker stops: its unacked messages are redelivered
            log.exception("ingest lane %d failed", i)
            self._lane_error = exc
            halt.set()

    def _gather(
        self, inbox: queue.Queue[mqtt.MQTTMessage], first: mqtt.MQTTMessage
    ) -> list[mqtt.MQTTMessage]:
        """The messages of one processing round: ``first``, whatever is already waiting and,
        while fewer than ``BUSY_MESSAGES`` are at hand, what arrives within ``batch_s``.

        The window groups a machine's messages into one transaction when traffic is light.
        Under load (a fleet replaying its backlog) the inbox already holds plenty: waiting
        out the window there only left the worker idle between rounds (a third of the time
        with 100 ms windows at 200 machines), so a full inbox is taken at once."""
        msgs = [first]
        deadline = time.monotonic() + self.batch_s
        while True:
            while True:  # whatever is already waiting
                try:
                    msgs.append(inbox.get_nowait())
                except queue.Empty:
                    break
            left = deadline - time.monotonic()
            if len(msgs) >= BUSY_MESSAGES or left <= 0:
                return msgs
            try:
                msgs.append(inbox.get(timeout=left))
            except queue.Empty:
                return msgs

    def _maintain(self, conn: psycopg.Connection[Any]) -> psycopg.Connection[Any]:
        """Telemetry partition maintenance, unless another worker is running it."""
        try:
            res = maintain(conn, self.retention_days, wait=False)
        except (psycopg.Error, RuntimeError) as exc:
            log.warning("telemetry partition maintenance failed: %s", exc)
            return self._reconnect(conn)
        if res is not None and (res.created or res.dropped or res.moved_rows):
            log.warning(
                "telemetry partitions: %d made, %d dropped (retention %d days), %d rows moved"
                " out of the default partition",
                len(res.created),
                len(res.dropped),
                res.retention_days,
                res.moved_rows,
            )
        return conn

    def _beat(self) -> None:
        """Touch FIELDRX_WORKER_HEARTBEAT (if set) while the broker and the database answer:
        the container health check reads its age."""
        path = os.environ.get("FIELDRX_WORKER_HEARTBEAT")
        if path and self.client.is_connected():
            with open(path, "a"):
                os.utime(path)

    def _reconnect(self, conn: psycopg.Connection[Any]) -> psycopg.Connection[Any]:
        try:
            conn.close()
        finally:
            time.sleep(0.5)
        return connect(self.dsn)

    def _process(
        self,
        conn: psycopg.Connection[Any],
        msgs: list[mqtt.MQTTMessage],
        stats: WorkerStats,
        held: dict[tuple[int, str], _Batch] | None = None,
    ) -> psycopg.Connection[Any]:
        """Store ``msgs`` and the batches ``held`` over from the previous round (first, so a
        machine's records stay in order); a batch whose machine another transaction holds
        is held over once (put back into ``held``), the second time waited for."""
        by_stream: dict[tuple[int, str], _Batch] = dict(held or {})
        again = set(by_stream)
        if held is not None:
            held.clear()
        for m in msgs:
            stats.messages += 1
            mid = _machine_of(m.topic)
            try:
                if mid is None:
                    raise IngestError("not a telemetry topic")
                batch = parse_batch(m.payload)
            except IngestError as exc:
                log.warning("dropping bad message on %s: %s", m.topic, exc)
                self.client.ack(m.mid, m.qos)
                continue
            entry = by_stream.get((mid, batch.stream))
            if entry is not None and entry[0].kind != batch.kind:
                log.warning("dropping message on %s: stream %r changed kind", m.topic, batch.stream)
                self.client.ack(m.mid, m.qos)
                continue
            if entry is None:
                by_stream[(mid, batch.stream)] = (batch, [m])
            else:
                entry[0].records.extend(batch.records)
                entry[0].stream_start = min(entry[0].stream_start, batch.stream_start)
                entry[1].append(m)
        for group in _rounds(list(by_stream.items())):
            conn = self._store_group(conn, group, stats, held, again)
        return conn

    def _store_group(
        self,
        conn: psycopg.Connection[Any],
        group: list[_Entry],
        stats: WorkerStats,
        held: dict[tuple[int, str], _Batch] | None = None,
        again: set[tuple[int, str]] | frozenset[tuple[int, str]] = frozenset(),
    ) -> psycopg.Connection[Any]:
        """A round's batches in one transaction (``multibatch.store_together``: one lock
        statement, one read round trip, one COPY, one NOTIFY, one COMMIT instead of each
        batch's own); the acks only after the commit. If it fails, nothing of it
        was committed or acked, and every batch is stored on its own (``_store_alone``), so
        one machine's bad batch neither loses nor blocks another machine's."""
        wait = False  # first the machines no other worker holds, then the rest (store_free)
        while len(group) > 1:
            try:
                works = [work_of(mid, batch) for (mid, _), (batch, _) in group]
                results = (store_together if wait else store_free)(conn, works)
            except (IngestError, psycopg.Error) as exc:
                log.info("%d batches stored one by one (%s)", len(group), reason_of(exc))
                if conn.closed or conn.broken:
                    stats.errors += 1
                    conn = self._reconnect(conn)
                break
            busy = []
            for e, result in zip(group, results, strict=True):
                if result is None and held is not None and e[0] not in again and not wait:
                    held[e[0]] = e[1]  # the next round tries it again (its machine is busy)
                elif result is None:
                    busy.append(e)
                else:
                    (mid, _), (batch, ms) = e
                    self._acked(stats, mid, batch, ms, result.to_json(), result)
            group, wait = busy, True
        for (mid, _), (batch, ms) in group:
            conn = self._store_alone(conn, mid, batch, ms, stats)
        return conn

    def _store_alone(
        self,
        conn: psycopg.Connection[Any],
        machine_id: int,
        batch: Batch,
        ms: list[mqtt.MQTTMessage],
        stats: WorkerStats,
    ) -> psycopg.Connection[Any]:
        """One batch in its own transaction, retried while the database is unreachable. A
        batch the database refuses (a constraint, a value it cannot take) gets an error ack
        naming it and the reason (``acked_seq`` 0: the agent trims nothing and resends),
        like a thin HTTP request's batch (``multibatch``); before, it was retried here
        forever and held up every other machine of the lane. A batch of a machine that
        does not exist (deleted while its messages were in flight) gets one too: it was
        PUBACKed without any ack, so its agent waited out its ack timeout and sent it
        again, with nothing in its log to say why."""
        what = f"batch ({batch.kind}, stream {batch.stream or '(legacy)'})"
        while True:
            try:
                result = store(conn, machine_id, batch)
            except IngestError as exc:
                log.warning("machine %s: %s not stored: %s", machine_id, what, exc)
                self._acked(stats, machine_id, batch, ms, error_ack(machine_id, batch, what, exc))
                return conn
            except psycopg.Error as exc:
                if not refused(exc):
                    stats.errors += 1
                    log.warning("ingest failed (%s); retrying", exc)
                    conn = self._reconnect(conn)
                    continue
                if conn.closed or conn.broken:
                    stats.errors += 1
                    conn = self._reconnect(conn)
                    continue
                log.warning("machine %s: %s not stored: %s", machine_id, what, reason_of(exc))
                self._acked(stats, machine_id, batch, ms, error_ack(machine_id, batch, what, exc))
                return conn
            else:
                self._acked(stats, machine_id, batch, ms, result.to_json(), result)
                return conn

    def _acked(
        self,
        stats: WorkerStats,
        machine_id: int,
        batch: Batch,
        ms: list[mqtt.MQTTMessage],
        ack: bytes,
        result: IngestResult | None = None,
    ) -> None:
        """Count a committed (or refused) batch, publish its ack, then PUBACK its messages."""
        if result is not None:
            stats.batches += 1
            stats.records += len(batch.records)
            stats.stored += result.stored
            stats.duplicates += result.duplicates
            stats.rejected += len(result.rejected)
        self.client.publish(ack_topic(machine_id), ack, qos=1)
        for m in ms:
            self.client.ack(m.mid, m.qos)


_Batch = tuple[Batch, list[mqtt.MQTTMessage]]  # a stream's batch and the messages it holds
_Entry = tuple[tuple[int, str], _Batch]


def _rounds(entries: list[_Entry]) -> list[list[_Entry]]:
    """The batches in transactions: at most one per machine and kind in each (a batch reads
    its machine's state before any batch of the transaction writes: ``store_together``).
    A machine's second stream of one kind goes to the next round, so its batches are
    still stored in the order they arrived."""
    rounds: list[list[_Entry]] = []
    seen: dict[tuple[int, str], int] = {}
    for e in entries:
        key = (e[0][0], e[1][0].kind)
        i = seen[key] = seen.get(key, -1) + 1
        if i == len(rounds):
            rounds.append([])
        rounds[i].append(e)
    return rounds
