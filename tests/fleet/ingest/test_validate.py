"""The validate stage: each record on its own -> a typed row or a reason, by the protocol's
field definitions and the columns' limits; the fast path and the general path agree."""

from __future__ import annotations

from typing import Any

import pytest
from fieldrx.fleet.ingest.model import INT8_MAX
from fieldrx.fleet.ingest.validate import (
    COLUMNS,
    FUTURE_TOLERANCE_S,
    TYPE_LIMITS,
    range_error,
    validate,
)
from fieldrx.fleet.telemetry_row import TELEMETRY_COPY
from fieldrx_edge.protocol import FLOAT_FIELDS, INT4_MAX, TELEMETRY_FIELDS, VALUE_RANGES

NOW = 1_790_000_000.0
M = 7


def rec(seq: int = 1, **kw: Any) -> dict[str, Any]:
    """A complete, plainly typed record (the fast path's)."""
    r: dict[str, Any] = {f: None for f in TELEMETRY_FIELDS}
    r.update(machine_id=M, seq=seq, t=NOW - 10.0 + seq * 0.1, lon=11.0, lat=48.0,
             fix_quality=4, hdop=0.8, speed_raw_m_s=2.0, heading_deg=90.0, job_id=3,
             cell_seq=5, target_rate_kg_ha=100.0, applied_rate_kg_ha=98.0,
             implement_down=True, alarms=[], queue_backlog=0, fix_period_s=0.1)  # fmt: skip
    r.update(kw)
    return r


def one(r: Any) -> tuple[Any, str | None]:
    rows, rejected, _, _ = validate([r], M, "s", NOW)
    return (next(iter(rows.values()), None), rejected[0]["reason"] if rejected else None)


def test_the_columns_table_covers_every_integer_column_up_to_its_type() -> None:
    """Every integer or boolean column a record field fills (besides the key) has its row
    in COLUMNS, bounded by what its column type holds."""
    col_type = dict(zip(TELEMETRY_COPY.columns, TELEMETRY_COPY.types, strict=True))
    want = {f for f in TELEMETRY_FIELDS if col_type.get(f) in TYPE_LIMITS} - {"machine_id"}
    assert {c.name for c in COLUMNS} == want
    assert TYPE_LIMITS["int2"] == (int, 32767) and TYPE_LIMITS["int4"] == (int, INT4_MAX)
    assert COLUMNS[0].reason == "fix_quality must be an integer 0..32767, got {!r}"


def test_general_path_builds_the_same_row_as_the_fast_path() -> None:
    fast, _ = one(rec())
    # ints where floats are expected, an extra field: the general path takes them
    slow, _ = one(rec(hdop=1, speed_raw_m_s=2, ndvi_raw=0.5))
    assert fast is not None and slow is not None
    assert slow._replace(hdop=0.8, ndvi_raw=None) == fast
    assert type(slow.hdop) is float and slow.ndvi_raw == 0.5
    v1, _ = one({k: v for k, v in rec().items() if k != "fix_period_s"})  # format 1
    assert v1 is not None and v1.fix_period_s is None


@pytest.mark.parametrize("col", COLUMNS, ids=lambda c: c.name)
def test_each_column_limit_is_refused_with_its_reason(col: Any) -> None:
    for bad in (col.lo - 1, col.hi + 1, "1", *(() if col.nullable else (None,))):
        if col.type is bool and isinstance(bad, int):
            bad = 1  # an integer is no boolean
        row, reason = one(rec(**{col.name: bad}))
        assert row is None and reason == col.reason.format(bad)
    if col.nullable:
        assert one(rec(**{col.name: None}))[1] is None
    top = True if col.type is bool else col.hi
    assert one(rec(**{col.name: top}))[1] is None


def test_the_key_and_the_time_come_first() -> None:
    assert one(rec(seq=INT8_MAX + 1, fix_quality=-1))[1] == f"seq {INT8_MAX + 1} out of range"
    t = NOW + FUTURE_TOLERANCE_S
    reason = one(rec(t=t, fix_quality=-1))[1]
    assert reason is not None and reason.startswith(f"t {t!r} is 300 s ahead")
    assert one(rec(t=t - 1.0))[1] is None


def test_float_ranges_are_the_protocols() -> None:
    for name in FLOAT_FIELDS:
        if name not in TELEMETRY_FIELDS:
            continue
        lo, hi = VALUE_RANGES[name]
        row, reason = one(rec(**{name: hi * 2 + 1.0}))
        assert row is None and reason == f"{name} {hi * 2 + 1.0!r} is out of range [{lo:g}, {hi:g}]"
    assert range_error([None] * len(FLOAT_FIELDS)) is None
    # a NaN or an infinity fails the fast path's range comparison: the protocol says why
    assert one(rec(hdop=float("nan")))[1] == "hdop must be a finite number or null, got nan"
    assert one(rec(duty=float("-inf")))[1] == "duty must be a finite number or null, got -inf"


def test_protocol_errors_keep_the_protocols_words() -> None:
    assert one(rec(lat=None))[1] == "lon and lat must both be given or both be null"
    assert one(rec(alarms=["nope"]))[1].startswith("alarms must be a list of")  # type: ignore[union-attr]
    assert one(rec(fix_period_s=61.0))[1] == "fix_period_s must be in (0, 60] s or null, got 61.0"
    assert one([1])[1] == "record is not a JSON object"


def test_rejects_other_machines_and_repeats() -> None:
    other = rec(seq=2, machine_id=M + 1)
    rows, rejected, dead, repeats = validate(
        [rec(seq=1), other, rec(seq=3, fix_quality=-1), rec(seq=1), {"seq": "x"}], M, "s", NOW
    )
    assert list(rows) == [1] and repeats == 1
    assert [r["seq"] for r in rejected] == [2, 3, None]
    assert "is not this device's machine" in rejected[0]["reason"]
    assert dead == {3}  # another machine's seq says nothing about this stream
