"""Telemetry ingest shared by HTTP and MQTT: the stages of this package, chained.

parse (the caller: ``parse.parse_batch`` / ``parse_request``) -> validate (each record
on its own, no database) -> [the caller's BEGIN and the machine's advisory lock] ->
read the machine and the stream (``stream``) -> deduplicate -> store (COPY) -> job spans,
ack walk, stream row, machine status -> live position -> progress -> alerts -> [NOTIFY of
the live messages, COMMIT]. One batch is one transaction (``store.store_alone``), or a
part of one shared with other batches (``fleet.multibatch``). The ack is sent after the
commit.

A batch names its stream (telemetry format 2, ``fieldrx_edge.protocol``): the random id
of the agent queue that numbered its records; a batch without a stream (format 1 agents)
belongs to the machine's legacy stream ''. A record whose ``machine_id`` differs from the
sending machine (the device token's, or the MQTT topic's) is rejected on its own and
does not advance ``acked_seq``: a device can only write its own machine's records.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import psycopg

from fieldrx.fleet.ingest import alerts, dedupe, progress, status, store
from fieldrx.fleet.ingest import stream as streams
from fieldrx.fleet.ingest.live import position_message
from fieldrx.fleet.ingest.model import IngestError, IngestResult, MachineInfo
from fieldrx.fleet.ingest.validate import validate
from fieldrx.fleet.partitions import FAR_PAST_REASON, is_far_past, job_spans_sql
from fieldrx.fleet.telemetry_row import TelemetryRow

LOCK_NS = 7001  # advisory lock namespace for per-machine ingest


def ingest(
    conn: psycopg.Connection[Any],
    machine_id: int,
    raw: list[Any],
    stream: str = "",
    stream_start: int = 1,
    streamed: bool | None = None,
) -> IngestResult:
    """Store one batch of ``stream`` for ``machine_id`` (already authenticated); the ack.

    ``stream_start``: the stream's first seq, used when the stream is new.
    ``streamed``: the batch was format 2 (default: a stream was named)."""
    return store.store_alone(conn, TrackWork.of(machine_id, raw, stream, stream_start, streamed))


@dataclass
class TrackWork:
    """One telemetry batch's part of a transaction, in the order the caller runs it:
    ``prepare`` (before the transaction), the caller's BEGIN and ``LOCK_SQL`` with
    ``lock_ns``, ``read`` / ``opened`` (after the lock), ``store`` (COPY), ``finish`` (the
    rest; returns the live messages), the caller's NOTIFY and COMMIT. ``result`` is the
    ack, true only once the caller committed. ``ingest`` runs one batch so;
    ``fleet.multibatch`` runs a thin request's track and cell batches in one transaction.
    """

    machine_id: int
    stream: str
    stream_start: int
    now: float
    rows: dict[int, TelemetryRow]
    dead: set[int]
    result: IngestResult
    info: MachineInfo | None = None
    new: list[TelemetryRow] = field(default_factory=list)
    conflict: int | None = None
    lock_ns: int = LOCK_NS

    @classmethod
    def of(
        cls,
        machine_id: int,
        raw: list[Any],
        stream: str = "",
        stream_start: int = 1,
        streamed: bool | None = None,
    ) -> TrackWork:
        """Validate the batch's records (no database)."""
        now = time.time()
        rows, rejected, dead, repeats = validate(raw, machine_id, stream, now)
        result = IngestResult(
            machine_id, stream_start - 1, rejected=rejected, duplicates=repeats, stream=stream,
            streamed=bool(stream) if streamed is None else streamed,
        )  # fmt: skip
        result.flagged = [
            {"seq": q, "reason": FAR_PAST_REASON} for q in sorted(rows) if is_far_past(rows[q].t)
        ]
        return cls(machine_id, stream, stream_start, now, rows, dead, result)

    def prepare(self, conn: psycopg.Connection[Any]) -> None:
        """Make the records' days (own transaction, before the batch's)."""
        store.make_days(conn, self.rows.values())

    def read(self, cur: psycopg.Cursor[Any]) -> None:
        """Queue the read of what the batch needs (after the caller's lock statement)."""
        streams.read_machine(cur, self.machine_id, self.stream)

    def opened(self, row: Any) -> None:
        """The read's row (``read``'s cursor's ``fetchone()``)."""
        info = self.info = streams.machine_info(row)
        if info is None:
            raise IngestError(f"machine {self.machine_id} does not exist")
        if info.acked_seq is not None:
            self.result.acked_seq = info.acked_seq

    def store(self, cur: psycopg.Cursor[Any]) -> None:
        """Sort out duplicates and a stream conflict; COPY the new rows."""
        self.sort(cur)
        self.copy_all(cur, [self])

    @staticmethod
    def copy_all(cur: psycopg.Cursor[Any], works: Sequence[TrackWork]) -> None:
        """One COPY of the sorted works' new rows (several machines' batches in one
        transaction: ``fleet.multibatch.store_together``)."""
        store.copy_rows(cur, [r for w in works for r in w.new])

    def sort(self, cur: psycopg.Cursor[Any]) -> None:
        """Sort out duplicates and a stream conflict: ``new``, the rows to COPY."""
        assert self.info is not None
        d = dedupe.deduplicate(
            cur, self.machine_id, self.stream, self.info, self.rows, self.dead, self.result
        )
        self.new, self.rows, self.dead, self.conflict = d.new, d.rows, d.dead, d.conflict

    def finish(self, cur: psycopg.Cursor[Any]) -> list[dict[str, Any]]:
        """Job spans, ack walk, stream row, status, per-cell sums, alerts; the live messages."""
        info, new, result, machine_id = self.info, self.new, self.result, self.machine_id
        assert info is not None
        result.acked_seq = streams.advance(
            cur, machine_id, self.stream, result.acked_seq, set(self.rows) | self.dead, info, new
        )
        stream_row = streams.stream_row(
            machine_id, self.stream, self.stream_start, result.acked_seq, new
        )
        if self.conflict is not None:
            # the agent may trim only below the conflict; it resends the rest on a new stream
            result.acked_seq = min(result.acked_seq, self.conflict - 1)
        # the job spans, the stream's row and the machine's status: one upsert each (as
        # common table expressions of one statement they were not one router plan on Citus,
        # which router-plans no INSERT inside WITH: three subplans through the coordinator)
        spans = job_spans_sql(machine_id, [r.t for r in new], [r.job_id for r in new])
        machine = status.status_upsert(machine_id, info, new, result.acked_seq, self.now)
        for part in (spans, stream_row, machine):
            if part is not None:
                cur.execute(*part)
        messages = alerts.far_past_alert(cur, machine_id, info, new)
        if new:
            latest = max(new, key=lambda r: r.t)
            messages.append(position_message(info.organisation_id, latest, result))
            messages.extend(
                progress.cell_progress(
                    cur, machine_id, info.organisation_id, progress.cell_sums(new)
                )
            )
        messages.extend(alerts.streams_alert(cur, machine_id, info, new, self.now))
        if new:
            messages.extend(alerts.record_alerts(cur, machine_id, info, new))
        return messages
