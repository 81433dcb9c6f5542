"""The alert stage: the events ingest raises itself, the cheap pre-check, and the record
rules run over a batch (no database: the answers are scripted)."""

from __future__ import annotations

from fieldrx.fleet.ingest.alerts import (
    CONCURRENT_WINDOW_S,
    far_past_alert,
    may_alert,
    record_alerts,
    streams_alert,
)

from tests.fleet.ingest.cursor import ScriptedCursor
from tests.fleet.ingest.rows import NOW, M, info, rows

OPENED = (None, (21,))  # open_event: no such alert open, then the INSERT's id


def test_far_past_records_open_one_event() -> None:
    old = rows(1, 2, t=978_307_200.0)  # 2001-01-01: a device clock reset
    cur = ScriptedCursor(*OPENED)
    (msg,) = far_past_alert(cur, M, info(), [*rows(3), *old])
    assert (msg["kind"], msg["event"], msg["id"]) == ("far_past_records", "started", 21)
    assert msg["message"].startswith("2 record(s) dated from 2001-01-01 00:00:0")
    assert far_past_alert(cur, M, info(event_alerts={"far_past_records": 4}), old) == []
    assert far_past_alert(cur, M, info(), rows(3)) == []


def test_two_streams_sending_at_once_open_duplicate_stream() -> None:
    both = info(stream_seen=NOW - 5.0, other_seen=NOW - 1.0)
    cur = ScriptedCursor(*OPENED)
    (msg,) = streams_alert(cur, M, both, rows(1), NOW)
    assert (msg["kind"], msg["job_id"]) == ("duplicate_stream", 3)
    already = info(
        stream_seen=NOW - 5.0, other_seen=NOW - 1.0, event_alerts={"duplicate_stream": 8}
    )
    assert streams_alert(cur, M, already, [], NOW) == []
    # a queue replaced by a new one (the other stream sent before this one): no alert
    assert streams_alert(cur, M, info(stream_seen=NOW - 1.0, other_seen=NOW - 5.0), [], NOW) == []


def test_duplicate_stream_ends_once_the_other_stream_is_quiet() -> None:
    quiet = NOW - CONCURRENT_WINDOW_S - 1.0
    cur = ScriptedCursor()
    state = info(other_seen=quiet, event_alerts={"duplicate_stream": 8})
    (msg,) = streams_alert(cur, M, state, [], NOW)
    assert (msg["id"], msg["event"]) == (8, "ended") and len(cur.executed) == 1


def test_most_batches_cannot_change_an_alert() -> None:
    assert not may_alert(rows(1, 2), info())
    assert may_alert(rows(1), info(open_alerts={"rate_error": 3}))
    assert may_alert(rows(1, fix_quality=0), info())
    assert may_alert(rows(1, alarms=["outside_field"]), info())
    assert may_alert(rows(1, speed_filtered_m_s=3.5), info())
    assert not may_alert(rows(1, speed_filtered_m_s=3.5, implement_down=False), info())
    assert may_alert(rows(1, applied_rate_kg_ha=120.0), info())


def test_record_rules_run_only_when_an_alert_may_change() -> None:
    cur = ScriptedCursor()
    assert record_alerts(cur, M, info(), rows(1, 2)) == [] and cur.executed == []
    # a fix lost for longer than the rule's duration: history read, then the alert opens
    cur = ScriptedCursor([], (11,))
    (msg,) = record_alerts(cur, M, info(), rows(*range(1, 31), fix_quality=0))
    assert (msg["kind"], msg["id"], msg["job_id"]) == ("fix_lost", 11, 3)


def test_depths_run_the_seeding_jobs_window() -> None:
    cur = ScriptedCursor(None)  # the job's kind: no such job
    assert record_alerts(cur, M, info(), rows(1, depth_mm=50.0)) == []
    assert "FROM jobs" in cur.executed[0][0]
