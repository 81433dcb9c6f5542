"""The MQTT ingest worker's lanes: a machine's messages always go to the same
lane (so its batches stay in order on one connection), and a lane count below one is a
clear error. The broker is not contacted: ``IngestWorker`` connects only in ``run``."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
from fieldrx.fleet.worker import IngestOptions, IngestWorker


def _worker(lanes: int) -> IngestWorker:
    opts = IngestOptions(client_id="t", db_connections=lanes)
    return IngestWorker("mqtt://127.0.0.1:1", dsn="postgresql:///unused", opts=opts)


def test_a_machine_always_lands_on_one_lane() -> None:
    w = _worker(3)
    for mid in (1, 2, 3, 4, 7, 1, 4, 1):
        w._on_message(None, None, SimpleNamespace(topic=f"fieldrx/machines/{mid}/telemetry"))
    got = [[m.topic.split("/")[2] for m in list(q.queue)] for q in w.inboxes]
    assert got == [["3"], ["1", "4", "7", "1", "4", "1"], ["2"]]
    assert w.stats.messages == 0  # counted when processed, summed over the lanes


def test_fewer_than_one_connection_is_refused() -> None:
    with pytest.raises(ValueError, match="db_connections must be at least 1, got 0"):
        _worker(0)
