"""The pipeline's first step, before any database: the batch validated, its ack started."""

from __future__ import annotations

import time

from fieldrx.fleet.ingest.pipeline import LOCK_NS, TrackWork
from fieldrx.fleet.partitions import FAR_PAST_REASON

from tests.fleet.ingest.rows import M


def rec(seq: int, t: float, **kw: object) -> dict[str, object]:
    return {"machine_id": M, "seq": seq, "t": t, **kw}


def test_a_batch_is_validated_and_its_ack_starts_below_the_stream() -> None:
    now = time.time()
    work = TrackWork.of(M, [rec(1, now), rec(2, 978_307_200.0), rec(3, now, hdop=-1.0)], "s", 41)
    assert sorted(work.rows) == [1, 2] and work.dead == {3} and work.lock_ns == LOCK_NS
    r = work.result
    assert (r.acked_seq, r.stream, r.streamed) == (40, "s", True)
    assert [x["seq"] for x in r.rejected] == [3]
    assert r.flagged == [{"seq": 2, "reason": FAR_PAST_REASON}]  # stored, with the reason
    assert not TrackWork.of(M, [], "").result.streamed  # format 1: the legacy stream
    assert TrackWork.of(M, [], "", streamed=True).result.streamed
