"""The data every ingest stage passes on: the parsed batch, the machine's state read under
the lock, the ack being built, and the column limits and time conversions they share."""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from typing import Any

import orjson
from fieldrx_edge.protocol import TelemetryAck

INT8_MAX = 2**63 - 1  # the int8 columns' limit (seq, stream_start)
PG_EPOCH_DT = dt.datetime(2000, 1, 1, tzinfo=dt.UTC)


class IngestError(ValueError):
    """The request as a whole is unusable (not JSON, no "records" list)."""


@dataclass
class Batch:
    records: list[Any]
    stream: str = ""
    stream_start: int = 1
    streamed: bool = False
    kind: str = "telemetry"  # "cells": uplink profile thin's cell records (fleet.cellrecords)


@dataclass
class IngestResult:
    machine_id: int
    acked_seq: int
    stored: int = 0
    duplicates: int = 0
    rejected: list[dict[str, Any]] = field(default_factory=list)
    stream: str = ""
    stream_conflict: bool = False
    streamed: bool = False  # the batch was format 2: the ack names its stream
    flagged: list[dict[str, Any]] = field(default_factory=list)  # stored, but see reason

    def ack(self) -> TelemetryAck:
        return TelemetryAck(
            machine_id=self.machine_id,
            acked_seq=self.acked_seq,
            stored=self.stored,
            duplicates=self.duplicates,
            rejected=self.rejected,
            stream=self.stream,
            stream_conflict=self.stream_conflict,
            flagged=self.flagged,
        )

    def to_json(self) -> bytes:
        """The ack as the agent reads it (``TelemetryAck``'s fields in order). orjson writes
        the dataclass itself: ``asdict`` deep-copied the rejects first, ~4 % of an API
        worker's CPU per thin request (py-spy, docs/scale.md section 5)."""
        if self.streamed:
            return orjson.dumps(self.ack())
        # a format 1 agent parses the ack strictly: only its fields
        return orjson.dumps(
            {
                "machine_id": self.machine_id,
                "acked_seq": self.acked_seq,
                "stored": self.stored,
                "duplicates": self.duplicates,
                "rejected": self.rejected,
            }
        )


@dataclass
class MachineInfo:
    """The machine and the batch's stream as read under the machine's lock
    (``stream.read_machine``)."""

    organisation_id: int
    speed_min_m_s: float
    speed_max_m_s: float
    acked_seq: int | None  # the stream's; None: a stream not seen before
    last_t: float | None
    open_alerts: dict[str, int]  # condition alerts (fleet.alerts.conditions) not ended
    stream_seen: float | None  # this stream's last batch (epoch s)
    other_seen: float | None  # the machine's other streams' last batch (epoch s)
    event_alerts: dict[str, int] = field(default_factory=dict)  # EVENT_KINDS not ended
    # the stream's highest stored seq and first/last record time (int8 us; None: nothing
    # stored): every stored record of the stream lies in that time range (migration 0010)
    max_seq: int | None = None
    first_us: int | None = None
    last_us: int | None = None


def ts(us: int) -> dt.datetime:
    """int8 microseconds since 2000-01-01 (the COPY row's t) -> timestamptz."""
    return PG_EPOCH_DT + dt.timedelta(microseconds=us)


def t_us(t: dt.datetime) -> int:
    """timestamptz -> int8 microseconds since 2000-01-01 (the COPY row's t), exactly."""
    return (t - PG_EPOCH_DT) // dt.timedelta(microseconds=1)
