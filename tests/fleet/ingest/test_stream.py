"""The stream's bookkeeping: the machine read under the lock, the ack walk, the stream row
(no database: the stored seqs are scripted)."""

from __future__ import annotations

import datetime as dt

from fieldrx.fleet.ingest.model import t_us
from fieldrx.fleet.ingest.stream import (
    ACK_PAGE,
    advance,
    advance_over_stored,
    machine_info,
    read_machine,
    stream_row,
)

from tests.fleet.ingest.cursor import ScriptedCursor
from tests.fleet.ingest.rows import M, info, rows


def test_the_machine_row_splits_event_alerts_from_condition_alerts() -> None:
    first = dt.datetime(2026, 1, 1, tzinfo=dt.UTC)
    row = (1, 0.5, 3.0, 41, 1.7e9, '{"fix_lost": 5, "duplicate_stream": 6}', 1.7e9, None,
           90, first, first + dt.timedelta(seconds=1))  # fmt: skip
    got = machine_info(row)
    assert got is not None
    assert got.open_alerts == {"fix_lost": 5} and got.event_alerts == {"duplicate_stream": 6}
    assert (got.acked_seq, got.max_seq, got.last_us - got.first_us) == (41, 90, 10**6)
    assert got.first_us == t_us(first)
    assert machine_info(None) is None
    cur = ScriptedCursor()
    read_machine(cur, M, "s")
    assert cur.executed[0][1] == {"s": "s", "m": M}


def test_the_ack_walks_over_done_and_stored_seqs_to_the_first_gap() -> None:
    stored = {3, 4, 6}
    asked: list[int] = []

    def above(a: int) -> list[int]:
        asked.append(a)
        return sorted(q for q in stored if q > a)

    assert advance_over_stored(above, 0, {1, 2, 5}) == 6  # 1 2 done, 3 4 stored, 5, 6
    assert advance_over_stored(above, 6, set()) == 6
    assert asked == [2, 6]


def test_the_ack_walk_pages_through_many_stored_seqs() -> None:
    n = ACK_PAGE * 2 + 10
    pages: list[int] = []

    def above(a: int) -> list[int]:
        pages.append(a)
        return list(range(a + 1, min(a + ACK_PAGE, n) + 1))

    assert advance_over_stored(above, 0, set()) == n and len(pages) == 3


def test_no_lookup_when_nothing_can_be_stored_above_the_ack() -> None:
    cur = ScriptedCursor()
    new = rows(1, 2, 3)
    assert advance(cur, M, "s", 0, {1, 2, 3}, info(), new) == 3
    assert advance(cur, M, "s", 0, set(), info(), []) == 0
    assert cur.executed == []
    # stored seqs above the ack may exist: looked up within the stream's time range
    cur = ScriptedCursor([(4,), (5,)])
    assert advance(cur, M, "s", 2, {3}, info(max_seq=5, first_us=new[0].t), []) == 5
    assert cur.executed[0][1][:3] == (M, "s", 3)


def test_the_stream_row_counts_and_spans_the_new_rows() -> None:
    new = rows(5, 6, 7)
    sql, params = stream_row(M, "s", 5, 7, new)
    assert sql.startswith("INSERT INTO telemetry_streams")
    assert params[:5] == (M, "s", 5, 7, 3) and params[7] == 7
    assert abs((params[6] - params[5]).total_seconds() - 0.2) < 1e-6
    _, legacy = stream_row(M, "", 5, 0, [])
    assert legacy[2] == 1 and legacy[4:] == (0, None, None, None)  # legacy: starts at 1
