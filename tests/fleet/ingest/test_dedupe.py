"""The dedupe stage: which valid rows are new on their stream, duplicates, and a stream
whose numbering went backwards (no database: the stored seqs are scripted)."""

from __future__ import annotations

from fieldrx.fleet.ingest.dedupe import conflict_reason, deduplicate, stored
from fieldrx.fleet.ingest.model import IngestResult, ts
from fieldrx.fleet.telemetry_row import TelemetryRow

from tests.fleet.ingest.cursor import ScriptedCursor
from tests.fleet.ingest.rows import M, info, rows


def by_seq(*seqs: int) -> dict[int, TelemetryRow]:
    return {r.seq: r for r in rows(*seqs)}


def test_a_new_stream_or_a_batch_above_the_stored_needs_no_lookup() -> None:
    cur = ScriptedCursor()
    assert stored(cur, M, "s", info(), by_seq(1, 2)) == {}
    assert stored(cur, M, "s", info(acked_seq=5, max_seq=5), by_seq(6, 7)) == {}
    assert cur.executed == []


def test_a_resend_is_looked_up_in_its_own_time_range_then_the_streams() -> None:
    new = by_seq(3, 4, 5)
    first, last = new[3].t - 10**6, new[5].t + 10**6
    cur = ScriptedCursor([(3, ts(new[3].t))], [])
    state = info(acked_seq=4, max_seq=4, first_us=first, last_us=last)
    got = stored(cur, M, "s", state, new)
    assert got == {3: new[3].t}
    (_, p1), (_, p2) = cur.executed
    assert p1[:4] == (M, "s", 3, 4)  # only the seqs up to the stream's highest stored
    assert p2[:4] == (M, "s", 4, 4) and p2[4] == ts(first)  # the rest: the whole stream


def test_duplicates_are_counted_and_not_stored_again() -> None:
    new = by_seq(1, 2, 3)
    result = IngestResult(M, 0)
    cur = ScriptedCursor([(1, ts(new[1].t)), (2, ts(new[2].t))])
    d = deduplicate(cur, M, "s", info(acked_seq=2, max_seq=2), new, set(), result)
    assert [r.seq for r in d.new] == [3] and d.conflict is None
    assert (result.duplicates, result.stored, result.rejected) == (2, 1, [])


def test_another_record_under_a_stored_seq_stops_the_batch_there() -> None:
    new = by_seq(1, 2, 3, 4)
    result = IngestResult(M, 0, duplicates=1)
    cur = ScriptedCursor([(1, ts(new[1].t)), (2, ts(new[2].t + 1))])
    d = deduplicate(cur, M, "s", info(acked_seq=2, max_seq=2), new, {5, 1}, result)
    assert d.conflict == 2 and result.stream_conflict
    assert d.new == [] and list(d.rows) == [1] and d.dead == {1}
    assert [r["seq"] for r in result.rejected] == [2, 3, 4]
    assert result.rejected[0]["reason"] == conflict_reason(2, "s", True)
    assert "follows a seq that does" in result.rejected[1]["reason"]
    assert (result.duplicates, result.stored) == (2, 0)
    assert "(legacy)" in conflict_reason(9, "", False)
