"""One job session: the job package, the telemetry sink (durable queue, thin profile), the
uplink sender thread and its drain, the job state reported to the server, and the live
state the cab display reads.

Every command that works a job (``run``, ``simulate``, ``ecu``, the sensor kinds, ``ndvi``)
builds one ``JobSession`` and passes ``session.put`` / ``session.put_many`` to its loop
(``ecu`` puts none: the TC side logs the drive). Records go through the session's
observers (the cab's live view, the operator's tags) and then into the queue, before
anything is sent. The session owns the sender thread, so stopping, draining and closing
it is written once.
"""

from __future__ import annotations

import logging
import tempfile
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.jobs import JobStore, post_state
from fieldrx_edge.protocol import mqtt_username
from fieldrx_edge.uplink.pacing import upload_period

log = logging.getLogger(__name__)

Observer = Callable[[dict[str, Any]], None]


class JobFinished(Exception):
    """Raised into a simulated drive's loop (through its sink) when the operator pressed
    Finish: the drive stops where it is; what was queued is still sent."""


@dataclass
class UplinkOptions:
    """Where telemetry goes: HTTP (``server`` + ``token``), MQTT (``mqtt`` HOST:PORT), or
    nowhere (``offline``: queued only). ``profile``: full or thin."""

    server: str | None = None
    token: str | None = None
    mqtt: str | None = None
    mqtt_ca: str | None = None
    offline: bool = False
    profile: str = "full"
    upload_period_s: float | None = None
    drain_timeout_s: float = 30.0

    @classmethod
    def from_args(cls, a: Any, store: JobStore | None = None) -> UplinkOptions:
        """From parsed CLI arguments; server and token fall back to ``pull``'s saved config."""
        cfg = store.config() if store is not None else {}
        return cls(
            server=getattr(a, "server", None) or cfg.get("server"),
            token=getattr(a, "token", None) or cfg.get("token"),
            mqtt=getattr(a, "mqtt", None),
            mqtt_ca=getattr(a, "mqtt_ca", None),
            offline=bool(getattr(a, "offline", False)),
            upload_period_s=getattr(a, "upload_period", None),
            drain_timeout_s=float(getattr(a, "drain_timeout", 30.0)),
        )


def make_sender(opts: UplinkOptions, queue: Any, extra: tuple[Any, ...] = ()) -> Any:
    """The uplink for ``queue`` (+ ``extra`` queues): MQTT, HTTP or None (offline)."""
    if opts.offline:
        return None  # --offline: queued only, whatever else is configured
    period = upload_period(opts.profile, opts.upload_period_s)
    if opts.mqtt:
        from fieldrx_edge.uplink import MqttBroker, MqttSender

        # the broker knows the machine as machine-<id>, its password is the device token
        if not opts.token:
            raise SystemExit("--mqtt needs the device token (--token, or saved by pull)")
        host, _, port = opts.mqtt.partition(":")
        broker = MqttBroker(
            host or "127.0.0.1",
            int(port or (8883 if opts.mqtt_ca else 1884)),
            username=mqtt_username(queue.machine_id),
            password=opts.token,
            tls_ca=opts.mqtt_ca,
        )
        return MqttSender(queue, broker, extra_queues=extra, upload_period_s=period)
    if opts.server and opts.token:
        from fieldrx_edge.uplink import HttpSender

        return HttpSender(
            queue, opts.server, opts.token, extra_queues=extra, upload_period_s=period
        )
    return None


def load_job(spec: str, store: JobStore | None = None) -> JobPackage:
    """A job from a file path, ``demo:35x23`` / ``demo:20ha``, or a cached job id."""
    if spec.startswith("demo:"):
        from fieldrx_edge.sim.fields import RectField, field_20ha, rect_job

        what = spec[5:]
        if what == "20ha":
            return field_20ha()
        length, _, width = what.partition("x")
        return rect_job(RectField(length_m=float(length), width_m=float(width)))
    p = Path(spec)
    if p.exists():
        return JobPackage.from_json(p.read_bytes(), verify=True)
    if spec.isdigit() and store is not None:
        if int(spec) in store.job_ids():
            return store.load(int(spec))
        raise SystemExit(
            f"job {spec}: not cached in {store.root} (cached: {store.job_ids() or 'none'});"
            " run `fieldrx-edge pull` with the same --state-dir first"
        )
    raise SystemExit(f"job {spec!r}: no such file, demo: spec or cached job id")


class JobSession:
    """A job being worked: records in (``put`` / ``put_many``), queued, sent by one thread.

    ``queue_path``: the durable queue's file (the state dir's, or a temporary one for a
    simulation without ``--state-dir``). ``machine_id`` overrides the job's (``ndvi``)."""

    def __init__(
        self,
        job: JobPackage | None,
        opts: UplinkOptions,
        queue_path: Path | None = None,
        machine_id: int | None = None,
    ) -> None:
        from fieldrx_edge.uplink import TelemetryQueue

        self.job = job
        self.opts = opts
        if queue_path is None:
            queue_path = Path(tempfile.mkdtemp(prefix="fieldrx-sim-")) / "queue.sqlite"
        self.root = queue_path.parent
        mid = machine_id if machine_id is not None else (job.machine_id if job else 1)
        self.queue = TelemetryQueue(queue_path, mid)
        self.thin: Any = None
        extra: tuple[Any, ...] = ()
        if opts.profile == "thin" and job is not None:
            from fieldrx_edge.uplink.thin import ThinUplink, raw_log_path

            # 1 Hz track + one record per cell left; the 10 Hz log stays in the state dir
            cells = TelemetryQueue(self.root / "cells.sqlite", job.machine_id, kind="cells")
            self.thin = ThinUplink(job, self.queue, cells, raw_log_path(self.root, job.job_id))
            extra = (cells,)
        self.sink: Any = self.thin if self.thin is not None else self.queue
        self.sender = make_sender(opts, self.queue, extra)
        self.observers: list[Observer] = []
        self.records = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.finish_requested = threading.Event()  # the cab's Finish button
        self.cab: Any = None  # the cab display's controls (fieldrx_edge.cab), when shown
        self.operator: Any = None  # ... and the operator's hand on the meter

    # -- records ---------------------------------------------------------

    def put(self, record: dict[str, Any]) -> int:
        for ob in self.observers:
            ob(record)
        self.records += 1
        return int(self.sink.put(record) or 0)

    def put_many(self, records: list[dict[str, Any]]) -> Any:
        if self.finish_requested.is_set():
            raise JobFinished()
        for rec in records:
            for ob in self.observers:
                ob(rec)
        self.records += len(records)
        return self.sink.put_many(records)

    def backlog(self) -> int:
        return int(self.sink.backlog())

    # -- uplink ----------------------------------------------------------

    def uplink_state(self) -> str:
        """offline (no uplink configured), online, unreachable, or connecting."""
        if self.sender is None:
            return "offline"
        return str(self.sender.state())

    def start(self, report: bool = True, wait: bool = True) -> None:
        """The sender thread; the job reported running (best effort; ``wait=False``: in a
        thread, so a tractor without network starts at once)."""
        if self.sender is not None:
            self._thread = threading.Thread(target=self.sender.run, args=(self._stop,), daemon=True)
            self._thread.start()
        if report:
            self.report_state("running", wait=wait)

    def report_state(self, state: str, wait: bool = True) -> bool:
        o = self.opts
        if self.job is None or o.offline or not (o.server and o.token):
            return False
        if not wait:
            threading.Thread(
                target=post_state, args=(o.server, o.token, self.job.job_id, state), daemon=True
            ).start()
            return True
        return post_state(o.server, o.token, self.job.job_id, state)

    def close(self, completed: bool = False, report: bool = True) -> dict[str, Any]:
        """Flush the thin profile's last cells, stop the sender, drain what is queued, close.
        Returns the uplink figures every command prints."""
        if self.thin is not None:
            self.thin.flush()  # the cells of this run's last seconds, before the job can end
        out: dict[str, Any] = {"drained": True}
        if self.cab is not None:
            self.cab.uploading()  # the screen says the job is driven, telemetry still going
        if self.sender is not None:
            self._stop.set()
            if self._thread is not None:
                self._thread.join(timeout=15.0)
            out["drained"] = bool(self.sender.drain(self.opts.drain_timeout_s))
            self.sender.close()
        if completed and report:
            out["job_state_reported"] = self.report_state("completed")
        out["queue"] = self.queue.stats()
        out["uplink"] = self.thin.stats() if self.thin is not None else {"profile": "full"}
        return out
