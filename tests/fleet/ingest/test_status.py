"""The status stage: the machine's latest state moves forward in record time only."""

from __future__ import annotations

from fieldrx.fleet.ingest.status import status_upsert
from fieldrx.fleet.ingest.validate import FUTURE_TOLERANCE_S

from tests.fleet.ingest.rows import NOW, M, info, rows


def test_a_batch_with_nothing_new_only_says_the_machine_was_seen() -> None:
    sql, params = status_upsert(M, info(), [], 41, NOW)
    assert "last_t" not in sql and params == (M, 41)


def test_the_latest_record_of_the_batch_becomes_the_state() -> None:
    new = rows(3, 1, 2, speed_filtered_m_s=None, speed_raw_m_s=1.5)
    sql, params = status_upsert(M, info(last_t=NOW - 200.0), new, 3, NOW)
    assert sql.strip().startswith("INSERT INTO machine_status")
    assert params[0] == M and params[1].timestamp() == new[0].t_s  # seq 3 is the latest
    assert params[2:8] == (3, 11.0, 48.0, 1.5, None, 3)  # raw speed when no filtered one


def test_an_older_batch_does_not_move_the_state_back() -> None:
    sql, params = status_upsert(M, info(last_t=NOW), rows(1), 5, NOW)
    assert sql.startswith("UPDATE machine_status SET last_seen_at") and params == (5, M)


def test_a_stored_time_beyond_the_future_tolerance_does_not_freeze_the_state() -> None:
    late = NOW + FUTURE_TOLERANCE_S + 1.0  # a clock error stored before
    sql, _ = status_upsert(M, info(last_t=late), rows(1), 5, NOW)
    assert sql.strip().startswith("INSERT INTO machine_status")
