"""MQTT sender: QoS 1 batches on fieldrx/machines/{id}/telemetry, acks on .../ack.

The broker's PUBACK only says the broker has the message; the queue is trimmed
only when the FieldRx server publishes its ``TelemetryAck`` (acked_seq). The
number of unacknowledged batches is capped well below paho's 65535 message
ids (docs/architecture.md, "Stack notes": publish fails with ERR_QUEUE_SIZE otherwise).
If no ack arrives for ``ack_timeout_s``, everything after acked_seq is sent again: the server
deduplicates by (machine, stream, seq).

Payloads are telemetry format 2 batches (``TelemetryQueue.pending_batch``).
Acks name their stream: every agent of a machine listens on the same ack
topic, so an ack for another stream (another agent, or a stream this queue
left) is ignored. Rejected records are logged with the server's reasons and
counted in the queue; a ``stream_conflict`` ack moves the unacknowledged
records to a new stream and resends them.

The broker admits no anonymous client: the machine logs in as
``mqtt_username(machine_id)`` with its device token as password, and may only
publish its own telemetry and read its own acks (server README, "MQTT security").
``tls_ca`` turns on TLS (production brokers listen on 8883 with TLS only).

Uplink profile ``thin`` has two queues (the 1 Hz track and the cell records,
``fieldrx_edge.uplink.thin``) on two streams: one client sends both (the
broker admits one session per machine), each queue a ``_Lane`` with its own
in-flight window, and an ack goes to the lane of its stream.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from dataclasses import dataclass
from typing import Any

import paho.mqtt.client as mqtt

from fieldrx_edge.protocol import TelemetryAck, ack_topic, mqtt_client_id, telemetry_topic
from fieldrx_edge.uplink.backoff import Backoff
from fieldrx_edge.uplink.pacing import UploadPacer
from fieldrx_edge.uplink.queue import TelemetryQueue

log = logging.getLogger(__name__)


class _Lane:
    """One queue's sending state: what the server acked, what is in flight, its stream."""

    def __init__(self, queue: TelemetryQueue) -> None:
        self.queue = queue
        self.acked = queue.acked_seq
        self.sent_up_to = self.acked
        self.inflight: list[tuple[int, float]] = []  # (last seq of batch, sent at)
        # set by the network thread, applied to the queue by the sending thread:
        # (acked_seq, rejects with reasons, stream conflict)
        self.pending_ack: tuple[int, list[dict[str, Any]], bool] | None = None
        self.stream = queue.stream[0]

    def resend_all(self) -> None:
        self.sent_up_to = self.acked
        self.inflight.clear()


@dataclass(frozen=True)
class MqttBroker:
    """Where the sender connects and as whom: the machine's broker login is
    ``mqtt_username(machine_id)`` with the device token as password; ``tls_ca`` turns on
    TLS. ``client_id`` defaults to ``mqtt_client_id(machine_id)``, the one the broker binds
    the login to."""

    host: str = "127.0.0.1"
    port: int = 1884
    username: str | None = None
    password: str | None = None
    tls_ca: str | None = None
    client_id: str | None = None
    topic_prefix: str = ""


class MqttSender:
    def __init__(
        self,
        queue: TelemetryQueue,
        broker: MqttBroker = MqttBroker(),
        batch_size: int = 200,
        max_inflight_batches: int = 20,
        ack_timeout_s: float = 10.0,
        extra_queues: tuple[TelemetryQueue, ...] = (),
        upload_period_s: float = 0.0,
    ) -> None:
        """``upload_period_s``: in ``run``, a batch that is not full waits this long after
        the previous upload (``pacing.UploadPacer``; 0: sent as soon as pending)."""
        self.pacer = UploadPacer(upload_period_s, batch_size)
        self.queue = queue
        self.lanes = [_Lane(q) for q in (queue, *extra_queues)]
        self.batch_size = batch_size
        self.max_inflight = max_inflight_batches
        self.ack_timeout_s = ack_timeout_s
        self.topic = broker.topic_prefix + telemetry_topic(queue.machine_id)
        self.ack_topic = broker.topic_prefix + ack_topic(queue.machine_id)
        self.backoff = Backoff(cap_s=10.0)
        self._cv = threading.Condition()
        self._connected = False
        cid = broker.client_id or mqtt_client_id(queue.machine_id)
        self.client = mqtt.Client(
            mqtt.CallbackAPIVersion.VERSION2, client_id=cid, clean_session=False
        )
        n_lanes = len(self.lanes)
        self.client.max_inflight_messages_set(max_inflight_batches * n_lanes)
        self.client.max_queued_messages_set(max_inflight_batches * 2 * n_lanes)
        if broker.username is not None:
            self.client.username_pw_set(broker.username, broker.password)
        if broker.tls_ca:
            self.client.tls_set(ca_certs=broker.tls_ca)
        self.client.on_connect = self._on_connect
        self.client.on_disconnect = self._on_disconnect
        self.client.on_message = self._on_message
        self.client.reconnect_delay_set(1, 10)  # paho takes whole seconds
        self.client.connect_async(broker.host, broker.port, keepalive=30)
        self.client.loop_start()

    def close(self) -> None:
        self.client.loop_stop()
        self.client.disconnect()

    def backlog(self) -> int:
        return sum(lane.queue.backlog() for lane in self.lanes)

    def state(self) -> str:
        """online (connected to the broker) or connecting (paho reconnects on its own)."""
        return "online" if self._connected else "connecting"

    # callbacks (paho network thread)
    def _on_connect(self, client, userdata, flags, reason_code, properties) -> None:  # noqa: ANN001
        if reason_code.is_failure:
            log.warning("MQTT broker refused the connection: %s", reason_code)
            return
        client.subscribe(self.ack_topic, qos=1)
        with self._cv:
            self._connected = True
            # after a reconnect, resend everything not acked by the server
            for lane in self.lanes:
                lane.resend_all()
            self._cv.notify_all()

    def _on_disconnect(self, client, userdata, flags, reason_code, properties) -> None:  # noqa: ANN001
        with self._cv:
            self._connected = False

    def _on_message(self, client, userdata, msg) -> None:  # noqa: ANN001
        try:
            obj = json.loads(msg.payload)
            ack = TelemetryAck.from_dict(obj)
            acked = int(ack.acked_seq)
            rejected = [r for r in ack.rejected if isinstance(r, dict)]
        except (ValueError, KeyError, TypeError, AttributeError):
            log.warning("bad ack payload on %s", msg.topic)
            return
        if obj.get("error"):  # not stored (acked_seq 0): resent after the ack timeout
            log.warning("server did not store a batch: %s", obj["error"])
        with self._cv:
            if ack.stream:
                lane = next((x for x in self.lanes if x.stream == ack.stream), None)
            else:
                lane = self.lanes[0]
            if lane is None:
                return  # another agent's (same machine) or a stream this queue left
            if rejected:
                log.warning("server rejected %d records: %s", len(rejected), rejected[:3])
            if acked > lane.acked:
                lane.acked = acked
                lane.inflight = [b for b in lane.inflight if b[0] > acked]
            pa = lane.pending_ack
            if pa is None:
                lane.pending_ack = (acked, rejected, ack.stream_conflict)
            else:
                conflict = pa[2] or ack.stream_conflict
                lane.pending_ack = (max(acked, pa[0]), pa[1] + rejected, conflict)
            self._cv.notify_all()

    def _apply_ack(self) -> None:
        for lane in self.lanes:
            with self._cv:
                pa = lane.pending_ack
                lane.pending_ack = None
            if pa is None:
                continue
            lane.queue.ack(pa[0], rejected=pa[1])
            if pa[2]:
                stream = lane.queue.new_stream()
                with self._cv:  # resend everything not acknowledged, on the new stream
                    lane.stream = stream
                    lane.acked = lane.queue.acked_seq
                    lane.resend_all()

    def send_some(self) -> int:
        """Publish batches while the in-flight caps allow; returns records published."""
        self._apply_ack()
        published = 0
        for lane in self.lanes:
            with self._cv:
                if not self._connected:
                    return published
                now = time.monotonic()
                if lane.inflight and now - lane.inflight[0][1] > self.ack_timeout_s:
                    log.info("no telemetry ack for %.0f s: resending", self.ack_timeout_s)
                    lane.resend_all()
                room = self.max_inflight - len(lane.inflight)
                after = max(lane.sent_up_to, lane.acked)
            while room > 0:
                payload, n, last = lane.queue.pending_batch(self.batch_size, after=after)
                if not n:
                    break
                info = self.client.publish(self.topic, payload, qos=1)
                if info.rc != mqtt.MQTT_ERR_SUCCESS:
                    break
                after = last
                with self._cv:
                    lane.sent_up_to = after
                    lane.inflight.append((after, time.monotonic()))
                published += n
                room -= 1
        return published

    def run(self, stop: threading.Event) -> None:
        """Publish until ``stop``, a batch that is not full at most once per upload period
        (a batch's worth unacknowledged is a backlog: at once; acks are applied meanwhile)."""
        while not stop.is_set():
            wait = self.pacer.due_in(lane.queue.backlog() for lane in self.lanes)
            if wait > 0:
                self._apply_ack()
                with self._cv:
                    self._cv.wait(min(wait, 0.2))
                continue
            n = self.send_some()
            if n:
                self.pacer.uploaded()
            with self._cv:
                if n == 0:
                    self._cv.wait(0.2)
        self._apply_ack()

    def drain(self, timeout_s: float = 30.0) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            self.send_some()
            self._apply_ack()
            if self.backlog() == 0:
                return True
            with self._cv:
                self._cv.wait(0.05)
        return self.backlog() == 0
