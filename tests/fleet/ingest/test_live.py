"""The live stage: the fleet view's messages of a batch."""

from __future__ import annotations

from fieldrx.fleet.ingest.live import job_messages, position_message
from fieldrx.fleet.ingest.model import IngestResult

from tests.fleet.ingest.rows import M, rows


def test_the_position_carries_the_record_and_the_ack() -> None:
    (r,) = rows(4, ndvi=0.6, alarms=["fix_lost"])
    msg = position_message(9, r, IngestResult(M, 4, stored=1))
    assert msg["type"] == "position" and msg["org"] == 9
    assert (msg["lon"], msg["lat"], msg["t"]) == (11.0, 48.0, r.t_s)
    assert (msg["seq"], msg["ndvi"], msg["alarms"], msg["acked_seq"], msg["stored"]) == (
        4,
        0.6,
        ["fix_lost"],
        4,
        1,
    )
    assert msg["speed_m_s"] == 2.0 and msg["sent_at"] > 0


def test_job_messages_give_progress_as_a_fraction() -> None:
    msgs = job_messages(M, 9, [(3, "running", 5, 20), (4, "running", 0, 0)])
    assert [(m["job_id"], m["progress"]) for m in msgs] == [(3, 0.25), (4, 0.0)]
    assert msgs[0] == {
        "type": "job", "org": 9, "job_id": 3, "machine_id": M, "state": "running",
        "cells_applied": 5, "n_cells": 20, "progress": 0.25,
    }  # fmt: skip
