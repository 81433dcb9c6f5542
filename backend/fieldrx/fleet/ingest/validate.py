"""Ingest stage 2, validate: each record on its own -> a typed ``TelemetryRow`` or a reason.

The rules are the protocol's (``TelemetryRecord.validate``: required fields, finite
numbers, lon/lat, alarms, the fix period; ``VALUE_RANGES`` per float field, what the agent
clamps to), plus what the server adds: the record is the sending machine's, its time is
no more than ``FUTURE_TOLERANCE_S`` ahead of the server clock, and every integer field
fits its column (``COLUMNS``). A bad record is rejected with its reason, the rest goes on.

Two paths apply the same tables. The fast path takes a complete, plainly typed record
(what agents send) straight to its row, or says "not sure" (None); everything else goes
through ``TelemetryRecord.from_dict`` (the protocol's own messages) and then the tables
with their reasons.
"""

from __future__ import annotations

import operator
import time
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from fieldrx_edge.protocol import (
    ALARMS,
    EXTRA_FIELDS,
    FLOAT_FIELDS,
    INT4_MAX,
    MAX_FIX_PERIOD_S,
    TELEMETRY_FIELDS,
    VALUE_RANGES,
    TelemetryRecord,
)

from fieldrx.fleet.ingest.model import INT8_MAX
from fieldrx.fleet.telemetry_row import (
    PG_EPOCH,
    TELEMETRY_COPY,
    TelemetryRow,
    ewkb_point,
    make_row,
)

# a record time this far ahead of the server clock is a clock error: stored, it would
# become the machine's latest state until real time caught up
FUTURE_TOLERANCE_S = 300.0
# what each integer or boolean COPY type of the telemetry columns holds: (Python type, max)
TYPE_LIMITS: dict[str, tuple[type, int]] = {
    "int2": (int, 2**15 - 1), "int4": (int, INT4_MAX), "bool": (bool, 1),
}  # fmt: skip
_COPY_TYPE = dict(zip(TELEMETRY_COPY.columns, TELEMETRY_COPY.types, strict=True))


@dataclass(frozen=True)
class Column:
    """A record field with an integer (or boolean) column: the values it takes, exactly
    of ``type`` (a bool is no integer here, an integer no bool) within ``lo..hi``."""

    name: str
    type: Any  # int or bool (Any: a value of it is compared with lo, hi)
    lo: int
    hi: int
    nullable: bool
    reason: str  # "... got {!r}": the value's repr goes in

    @classmethod
    def of(cls, name: str, lo: int, nullable: bool, reason: str) -> Column:
        """The field's column: its type and upper limit from the column's COPY type
        (``fleet.telemetry_row``); ``{hi}`` in ``reason`` is that limit."""
        typ, hi = TYPE_LIMITS[_COPY_TYPE[name]]
        return cls(name, typ, lo, hi, nullable, reason.replace("{hi}", str(hi)))

    def error(self, v: Any) -> str | None:
        if v is None and self.nullable:
            return None
        if type(v) is not self.type or not self.lo <= v <= self.hi:
            return self.reason.format(v)
        return None


# the integer and boolean fields after the record's key (machine_id, seq), in the order
# their reasons are reported, with the lower bounds the protocol gives them
# (sanitize_record: a cell_seq of -INT4_MAX..INT4_MAX, a positive job_id)
COLUMNS = (
    Column.of("fix_quality", 0, False, "fix_quality must be an integer 0..{hi}, got {!r}"),
    Column.of("job_id", 1, True, "job_id must be a positive integer or null, got {!r}"),
    Column.of("cell_seq", -INT4_MAX, True, "cell_seq must be an integer or null, got {!r}"),
    Column.of("implement_down", 0, False, "implement_down must be true or false, got {!r}"),
    Column.of("queue_backlog", 0, False, "queue_backlog must be a non-negative integer, got {!r}"),
)

# each float field's accepted range, in FLOAT_FIELDS order (the protocol's VALUE_RANGES:
# what the agent clamps to), so a value outside is refused with its reason, never stored
_RANGES = tuple((name, *VALUE_RANGES[name]) for name in FLOAT_FIELDS)


def range_error(values: Any) -> str | None:
    """The first float field (in FLOAT_FIELDS order) outside its range, as a reason."""
    for (name, lo, hi), v in zip(_RANGES, values, strict=False):
        if v is not None and not lo <= v <= hi:
            return f"{name} {v!r} is out of range [{lo:g}, {hi:g}]"
    return None


# The fast path reads a record's values in TELEMETRY_FIELDS order with one itemgetter
_GET_ALL = operator.itemgetter(*TELEMETRY_FIELDS)
_GET_V1 = operator.itemgetter(*TELEMETRY_FIELDS[:-1])  # format 1: no fix_period_s
_N_FIELDS = len(TELEMETRY_FIELDS)
_AT = TELEMETRY_FIELDS.index
# the fast path's one table of the typed fields: (index, the exact type, lo, hi, nullable)
# for the integer and boolean columns, then for the float fields with the protocol's ranges
# (a NaN or an infinity fails the comparison, so finite needs no test of its own)
_PLAIN = tuple((_AT(c.name), c.type, c.lo, c.hi, c.nullable) for c in COLUMNS) + tuple(
    (_AT(n), float, *VALUE_RANGES[n], True) for n in FLOAT_FIELDS if n in TELEMETRY_FIELDS
)
_ALARM_SET = frozenset(ALARMS)
_NO_EXTRAS = (None,) * len(EXTRA_FIELDS)  # records with extras take the general path
# the row is built from the values by position: the protocol's field order, checked here
assert TELEMETRY_FIELDS == (
    "machine_id", "seq", "t", "lon", "lat", "fix_quality", "hdop", "speed_raw_m_s",
    "speed_filtered_m_s", "heading_deg", "job_id", "cell_seq", "target_rate_kg_ha",
    "applied_rate_kg_ha", "target_shaft_rpm", "actual_shaft_rpm", "duty", "ndvi", "depth_mm",
    "implement_down", "alarms", "queue_backlog", "fix_period_s",
)  # fmt: skip


def _values(d: Any) -> tuple[Any, ...] | None:
    """All of a record's fields in TELEMETRY_FIELDS order, if it has exactly those (a format
    1 record without ``fix_period_s``); else None."""
    if type(d) is not dict:
        return None
    n = len(d)  # n keys, all n fields present: exactly the fields (no subset test)
    try:
        if n == _N_FIELDS:
            return _GET_ALL(d)
        if n == _N_FIELDS - 1:
            return (*_GET_V1(d), None)
    except KeyError:
        pass
    return None


def _plain(values: tuple[Any, ...], machine_id: int, t_max: float) -> bool:
    """Whether a record's values pass every rule, each value plainly typed (floats as
    floats): the fast path's check. False means "not sure": the general path decides."""
    m, s, t = values[0], values[1], values[2]
    if m != machine_id or type(s) is not int or not 1 <= s <= INT8_MAX:
        return False
    if type(t) is not float or not 0.0 < t < t_max:
        return False
    for i, typ, lo, hi, nullable in _PLAIN:
        v = values[i]
        if type(v) is not typ or not lo <= v <= hi:
            if v is None and nullable:
                continue
            return False
    alarms, period = values[-3], values[-1]
    if type(alarms) is not list or (alarms and not _ALARM_SET.issuperset(alarms)):
        return False
    return period is None or (type(period) is float and 0.0 < period <= MAX_FIX_PERIOD_S)


def _fast_row(d: Any, machine_id: int, t_max: float, stream: str) -> TelemetryRow | None:
    """A complete, plainly typed record (what agents send) -> COPY row; else None."""
    values = _values(d)
    if values is None or not _plain(values, machine_id, t_max):
        return None
    (m, s, t, lon, lat, fq, hdop, sraw, sfil, head, job, cell, trate, arate, trpm, arpm, duty,
     ndvi, depth, down, alarms, backlog, period) = values  # fmt: skip
    if lon is None:
        if lat is not None:
            return None
        geom = None
    else:
        if type(lon) is not float or type(lat) is not float:
            return None
        if not (-180.0 <= lon <= 180.0 and -90.0 <= lat <= 90.0):
            return None
        geom = ewkb_point(lon, lat)
    return make_row(
        m, s, int((t - PG_EPOCH) * 1e6), job, geom, fq, hdop, sraw, sfil, head, cell, trate,
        arate, trpm, arpm, duty, ndvi, depth, down, alarms, backlog, period, stream, *_NO_EXTRAS,
    )  # fmt: skip


def _slow_row(d: Any, machine_id: int, now: float, stream: str) -> TelemetryRow | str:
    """Any record: the protocol's own validation, then the server's tables. Row or reason."""
    try:
        rec = TelemetryRecord.from_dict(d)
    except Exception as exc:  # ProtocolError, or TypeError/OverflowError from odd values
        return str(exc) or type(exc).__name__
    if rec.machine_id != machine_id:
        return f"machine_id {rec.machine_id} is not this device's machine ({machine_id})"
    if rec.seq > INT8_MAX:
        return f"seq {rec.seq} out of range"
    if rec.t >= now + FUTURE_TOLERANCE_S:
        return (
            f"t {rec.t!r} is {rec.t - now:.0f} s ahead of the server clock (tolerance"
            f" {FUTURE_TOLERANCE_S:g} s): clock error"
        )
    for col in COLUMNS:
        bad = col.error(getattr(rec, col.name))
        if bad is not None:
            return bad
    try:
        f = [None if v is None else float(v) for v in (getattr(rec, n) for n in FLOAT_FIELDS)]
        period = None if rec.fix_period_s is None else float(rec.fix_period_s)
    except OverflowError:
        return "a number is too large"
    bad = range_error(f)
    if bad is not None:
        return bad
    geom = None
    if rec.lon is not None and rec.lat is not None:
        geom = ewkb_point(float(rec.lon), float(rec.lat))
    return make_row(
        rec.machine_id, rec.seq, int((rec.t - PG_EPOCH) * 1e6), rec.job_id, geom,
        rec.fix_quality, *f[:4], rec.cell_seq, *f[4:11], rec.implement_down, list(rec.alarms),
        rec.queue_backlog, period, stream, *f[11:],
    )  # fmt: skip


def validate(
    raw: Iterable[Any], machine_id: int, stream: str = "", now: float | None = None
) -> tuple[dict[int, TelemetryRow], list[dict[str, Any]], set[int], int]:
    """Split records into valid rows by seq, rejects, rejected-for-good seqs and in-batch repeats.

    ``now``: the server clock (record times beyond it plus ``FUTURE_TOLERANCE_S`` are
    rejected). A rejected record's seq is rejected for good (resending it can never
    succeed) unless it names another machine: a device can only write its own machine's
    records, and another machine's seq says nothing about this stream.
    """
    now = time.time() if now is None else now
    t_max = now + FUTURE_TOLERANCE_S
    rows: dict[int, TelemetryRow] = {}
    rejected: list[dict[str, Any]] = []
    dead: set[int] = set()
    repeats = 0
    for d in raw:
        fast = _fast_row(d, machine_id, t_max, stream)
        r = fast if fast is not None else _slow_row(d, machine_id, now, stream)
        if isinstance(r, str):
            seq = d.get("seq") if isinstance(d, dict) else None
            if type(seq) is not int or seq < 1:
                seq = None
            rejected.append({"seq": seq, "reason": r})
            mid = d.get("machine_id") if isinstance(d, dict) else None
            if seq is not None and (mid is None or mid == machine_id):
                dead.add(seq)
            continue
        if r.seq in rows:
            repeats += 1
        else:
            rows[r.seq] = r
    return rows, rejected, dead, repeats
