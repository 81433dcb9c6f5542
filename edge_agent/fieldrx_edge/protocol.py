"""The wire format between the FieldRx server and the edge agent: the one definition.

Two messages cross the network:

* ``JobPackage`` (server -> tractor): a prescription bound to a machine. Cells
  are stored column-wise in path order (seed 001 sec. 1.2, Table 1: cell id,
  four corner coordinates, rate), with UTM corners for the agent's metric
  work and WGS84 corners for display and cross-checks. A SHA-256 checksum over
  the canonical JSON lets the agent verify what it cached.
* ``TelemetryRecord`` (tractor -> server): one record per GNSS fix, numbered
  per stream (``seq``) so the server can deduplicate and acknowledge the
  highest contiguous number it stored. Records travel in batches
  (``telemetry_batch``) that name their stream: a random id the agent's queue
  creates with itself, so a machine whose queue is lost or replaced (new
  tablet, wiped state, a second agent) starts a new stream instead of reusing
  numbers the server already holds. The server deduplicates by
  (machine, stream, seq).
* ``CellRecord`` (tractor -> server, uplink profile ``thin``): one record per
  cell the tractor left, with the cell's as-applied figures computed on the
  tractor by the as-applied kernel over its full 10 Hz log
  (``fieldrx_edge.uplink.thin``). They travel on their own stream, in cell
  batches (``cell_batch_json``: format 3, ``"kind": "cells"``), with the same
  numbering, deduplication and acknowledgement as telemetry records. The thin
  profile's 1 Hz track travels as ordinary telemetry records.

This module holds the format versions, the job kinds, ``TelemetryRecord`` with its
alarms, value ranges and sanitizing, batches, the acknowledgement and the MQTT names;
``JobPackage`` is in ``job_package`` and ``CellRecord`` in ``cell_records``.

Only the standard library is used here, so the server and the agent share it
without pulling each other's dependencies.
"""

from __future__ import annotations

import math
import re
import uuid
from dataclasses import dataclass, field, fields
from typing import Any, TypeGuard

FORMAT_VERSION = 1
# Telemetry wire format. 1: batches {"records": [...]}, deduplicated by (machine, seq).
# 2: batches also carry "format", "stream" and "stream_start"; records may carry
# fix_period_s and the "invalid_value" alarm. A version 1 batch is still accepted
# (stream "", the machine's legacy stream); a version 2 agent needs a version 2 server.
TELEMETRY_FORMAT_VERSION = 2
# Cell batches (uplink profile "thin"): {"format": 3, "kind": "cells", "stream", "stream_start",
# "records": [CellRecord, ...]}. Track batches stay format 2, so a full-profile agent still
# talks to a format 2 server; a thin agent needs a server that knows format 3.
CELL_FORMAT_VERSION = 3
# Several batches in one HTTP request (a thin agent's track and cell batches: one request,
# one token check, instead of two): {"format": 3, "kind": "batches", "batches": [batch, ...]}
# with each batch as above; the answer is {"acks": [TelemetryAck, ...]}, one per batch in
# order. An ack with "error" is a batch the server could not store (acked_seq 0:
# nothing is trimmed, the batch is resent); the others are stored and acked as usual.
MULTI_KIND = "batches"
MAX_BATCHES = 8
UPLINK_PROFILES = ("full", "thin")  # full: every fix; thin: 1 Hz track + one record per cell
# Seconds an agent online waits, after an upload, before it sends a batch that is not full
# (a full batch goes at once: a backlog drains at full speed). A request's fixed server
# cost (token, transaction, locks, statements: ~4-6 ms of CPU) dwarfs a small batch's
# records, so the cadence, not the record count, sets the server's CPU per machine-hour in
# real time (docs/scale.md section 5, seventh round: sending whenever anything was
# pending, the thin profile cost the server only 1.2 x less than full). full: the live
# map's 1 s; thin (the economy profile): 10 s, its 1 Hz track arriving in 10 s pieces.
UPLOAD_PERIOD_S = {"full": 1.0, "thin": 10.0}


class ProtocolError(ValueError):
    """A message does not follow the wire format; the text says which field and why."""


JOB_KINDS = ("prescription_map", "ndvi_topdress", "seeding_depth")


ALARMS = (
    "fix_lost",  # no usable GNSS fix
    "shaft_below_range",  # target shaft speed below the calibrated range
    "shaft_above_range",  # target shaft speed above the calibrated range (saturation)
    "speed_out_of_range",  # ground speed outside the job's planned range
    "rate_error",  # applied rate off target beyond tolerance
    "outside_field",  # machine outside the boundary: metering stopped
    "motor_saturated",  # controller output at its limit
    # ISOBUS implement (fieldrx_edge.isobus): the TC server's view of the bus and client
    "isobus_no_client",  # no implement connected: nothing is metered
    "isobus_client_lost",  # the connected implement went silent: metering paused
    "isobus_wrong_ddop",  # an implement's device description breaks the pool rules: refused
    "isobus_cannot_drive",  # a valid pool the TC cannot drive (no rate it converts to)
    "isobus_width_unknown",  # the implement states no working width: not checked
    "isobus_sections_manual",  # the implement's section control is in manual (DDI 160)
    "isobus_rate_manual",  # the implement's prescription control is in manual (DDI 158)
    "isobus_pdack_error",  # the implement refused a process data command
    "isobus_width_mismatch",  # implement working width differs from the job's
    "isobus_bus_off",  # CAN send/receive failing
    "isobus_address_lost",  # our address was taken by a higher-priority NAME
    "isobus_address_conflict",  # another node transmitted with our address
    "invalid_value",  # the agent nulled or clamped a field that broke the protocol (sanitize)
    "sensor_fault",  # crop / depth sensor reading rejected (format, checksum, range): holding
    "sensor_lost",  # no good sensor reading for longer than the hold time: output stopped
    # raised by the cab display (fieldrx_edge.cab) over the records it sees
    "gnss_degraded",  # a fix, but its HDOP beyond the cab's limit
    "uplink_backlog_high",  # more records queued on the tractor than the cab's limit
    # the operator's hand (fieldrx_edge.cab.operator), on every record while in force
    "operator_pause",  # metering paused by the operator
    "operator_rate_override",  # the shaft follows the prescription +- the operator's percent
    "operator_section_off",  # a section switched off by hand
    "alarm_ack",  # the operator acknowledged the alarms this record also names
)


@dataclass(slots=True)
class TelemetryRecord:
    """One record per GNSS fix (or per NDVI/depth sample), as stored on the server.

    (machine_id, stream, seq) is the deduplication key (the stream travels with
    the batch); seq increases by one per record, so the server can acknowledge
    the highest contiguous seq of the stream.

    ``t`` is the time of the GNSS fix the record describes (receiver time, unix
    seconds), never the time the record was written or sent: the as-applied
    report integrates metered mass over record time. ``fix_period_s`` is the
    fix period the record stands for (the receiver's fix interval): metering
    described by this record lasts that long. The report integrates over it
    when given (``fieldrx_edge.asapplied.fix_periods``), so compressed or
    stretched time stamps cannot scale the applied mass.
    """

    machine_id: int
    seq: int
    t: float  # unix time, s
    lon: float | None = None
    lat: float | None = None
    fix_quality: int = 0  # GGA quality: 0 none, 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float
    hdop: float | None = None
    speed_raw_m_s: float | None = None
    speed_filtered_m_s: float | None = None
    heading_deg: float | None = None
    job_id: int | None = None
    cell_seq: int | None = None
    target_rate_kg_ha: float | None = None
    applied_rate_kg_ha: float | None = None
    target_shaft_rpm: float | None = None
    actual_shaft_rpm: float | None = None
    duty: float | None = None
    ndvi: float | None = None
    depth_mm: float | None = None
    implement_down: bool = False
    alarms: list[str] = field(default_factory=list)
    queue_backlog: int = 0
    fix_period_s: float | None = None  # format 2; absent in format 1 records
    # optional fields of the sensor job kinds; sent only when set, so records of
    # prescription-map jobs keep their exact shape (see EXTRA_FIELDS)
    ndvi_raw: float | None = None  # mean of the canopy sensors before the window filter
    actuator_mm: float | None = None  # press-roller cylinder position (seed 002)
    gain_kp: float | None = None  # controller gains in force (fuzzy PID retunes them)
    gain_ki: float | None = None
    gain_kd: float | None = None

    def to_dict(self) -> dict[str, Any]:
        d = {f: getattr(self, f) for f in TELEMETRY_FIELDS}
        for f in EXTRA_FIELDS:
            v = getattr(self, f)
            if v is not None:
                d[f] = v
        return d

    @classmethod
    def from_dict(cls, obj: dict[str, Any]) -> TelemetryRecord:
        """Parse and validate one record; ``ProtocolError`` names the offending field."""
        if not isinstance(obj, dict):
            raise ProtocolError("record is not a JSON object")
        unknown = set(obj) - _ALL_FIELD_SET
        if unknown:
            raise ProtocolError(f"unknown fields {sorted(unknown)}")
        for name in ("machine_id", "seq", "t"):
            if name not in obj:
                raise ProtocolError(f"missing required field '{name}'")
        rec = cls(**obj)
        rec.validate()
        return rec

    def validate(self) -> None:
        if not isinstance(self.machine_id, int) or self.machine_id <= 0:
            raise ProtocolError("machine_id must be a positive integer")
        if not isinstance(self.seq, int) or isinstance(self.seq, bool) or self.seq < 1:
            raise ProtocolError("seq must be an integer >= 1")
        if not isinstance(self.t, int | float) or not math.isfinite(self.t) or self.t <= 0:
            raise ProtocolError("t must be a positive unix time in seconds")
        if (self.lon is None) != (self.lat is None):
            raise ProtocolError("lon and lat must both be given or both be null")
        if self.lon is not None:
            if not isinstance(self.lon, int | float) or not -180.0 <= self.lon <= 180.0:
                raise ProtocolError(f"lon {self.lon!r} out of range [-180, 180]")
            if not isinstance(self.lat, int | float) or not -90.0 <= self.lat <= 90.0:
                raise ProtocolError(f"lat {self.lat!r} out of range [-90, 90]")
        for name in _FLOAT_FIELDS:
            v = getattr(self, name)
            if v is not None and (
                not isinstance(v, int | float) or isinstance(v, bool) or not math.isfinite(v)
            ):
                raise ProtocolError(f"{name} must be a finite number or null, got {v!r}")
        if not isinstance(self.alarms, list) or any(a not in ALARMS for a in self.alarms):
            raise ProtocolError(f"alarms must be a list of {list(ALARMS)}, got {self.alarms!r}")
        p = self.fix_period_s
        if p is not None and (
            not isinstance(p, int | float)
            or isinstance(p, bool)
            or not (0.0 < p <= MAX_FIX_PERIOD_S)
        ):
            raise ProtocolError(
                f"fix_period_s must be in (0, {MAX_FIX_PERIOD_S:g}] s or null, got {p!r}"
            )


EXTRA_FIELDS: tuple[str, ...] = ("ndvi_raw", "actuator_mm", "gain_kp", "gain_ki", "gain_kd")
TELEMETRY_FIELDS: tuple[str, ...] = tuple(
    f.name for f in fields(TelemetryRecord) if f.name not in EXTRA_FIELDS
)
FIELD_SET = _FIELD_SET = frozenset(TELEMETRY_FIELDS)
_ALL_FIELD_SET = frozenset(TELEMETRY_FIELDS + EXTRA_FIELDS)
FLOAT_FIELDS = _FLOAT_FIELDS = (
    "hdop",
    "speed_raw_m_s",
    "speed_filtered_m_s",
    "heading_deg",
    "target_rate_kg_ha",
    "applied_rate_kg_ha",
    "target_shaft_rpm",
    "actual_shaft_rpm",
    "duty",
    "ndvi",
    "depth_mm",
    *EXTRA_FIELDS,
)


MAX_FIX_PERIOD_S = 60.0
INT4_MAX = 2**31 - 1
# plausible ranges the agent clamps to before queueing (sanitize_record)
_CLAMP = {
    "hdop": (0.0, 99.99),
    "speed_raw_m_s": (0.0, 100.0),
    "speed_filtered_m_s": (0.0, 100.0),
    "target_rate_kg_ha": (0.0, 1.0e5),
    "applied_rate_kg_ha": (0.0, 1.0e5),
    "target_shaft_rpm": (0.0, 1.0e5),
    "actual_shaft_rpm": (-1.0e5, 1.0e5),
    "duty": (-100.0, 100.0),
    "ndvi": (-1.0, 1.0),
    "depth_mm": (-1.0e4, 1.0e4),
    # optional fields of the sensor job kinds (EXTRA_FIELDS)
    "ndvi_raw": (-1.0, 1.0),
    "actuator_mm": (-1.0e4, 1.0e4),
    "gain_kp": (-1.0e6, 1.0e6),
    "gain_ki": (-1.0e6, 1.0e6),
    "gain_kd": (-1.0e6, 1.0e6),
}
assert set(_CLAMP) | {"heading_deg"} == set(_FLOAT_FIELDS), "every float field has a range"
# what a server accepts per float field: the agent's clamp ranges, a heading in degrees
VALUE_RANGES: dict[str, tuple[float, float]] = {**_CLAMP, "heading_deg": (0.0, 360.0)}


def finite(v: object) -> TypeGuard[float]:
    """A real, finite number (bool excluded); narrows ``v`` for the comparisons after it."""
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _sanitize_floats(rec: dict[str, Any], reasons: list[str]) -> None:
    """``sanitize_record``'s measured values: non-finite to null, out of range clamped,
    a heading wrapped into [0, 360)."""
    for name in _FLOAT_FIELDS:
        v = rec.get(name)
        if v is None:
            continue
        if not finite(v):
            reasons.append(f"{name}: {v!r} is not a finite number")
            rec[name] = None
            continue
        if name == "heading_deg":
            if not 0.0 <= v < 360.0:
                rec[name] = float(v) % 360.0  # a direction: wrap, not an error
            continue
        lo, hi = _CLAMP[name]
        if v < lo or v > hi:
            reasons.append(f"{name}: {v!r} clamped to [{lo:g}, {hi:g}]")
            rec[name] = min(max(float(v), lo), hi)


def _sanitize_ids(rec: dict[str, Any], reasons: list[str]) -> None:
    """``sanitize_record``'s ids: what does not fit the server's int4 columns becomes null."""
    for name in ("job_id", "cell_seq"):
        v = rec.get(name)
        if v is not None and (type(v) is not int or not -INT4_MAX <= v <= INT4_MAX):
            reasons.append(f"{name}: {v!r} is not an integer id")
            rec[name] = None
    if rec.get("job_id") is not None and rec["job_id"] <= 0:
        reasons.append(f"job_id: {rec['job_id']!r} is not a positive id")
        rec["job_id"] = None


def sanitize_record(rec: dict[str, Any]) -> list[str]:
    """Make a record the agent is about to queue follow the protocol, in place.

    Returns the reasons (``"field: what"``) for everything changed; an empty
    list means the record was already clean. Non-finite numbers (a NaN HDOP
    from a receiver) become null, out-of-range values are clamped or nulled,
    and the record gets the ``invalid_value`` alarm so the change is visible.
    A record whose time is unusable cannot be repaired: the reason list then
    starts with ``"drop: ..."`` and the caller must not queue it. One bad value
    must never block the records behind it.
    """
    reasons: list[str] = []
    t = rec.get("t")
    if not finite(t) or t <= 0:
        return [f"drop: t {t!r} is not a positive finite unix time"]
    lon, lat = rec.get("lon"), rec.get("lat")
    if lon is not None or lat is not None:
        if not (finite(lon) and finite(lat) and -180.0 <= lon <= 180.0 and -90.0 <= lat <= 90.0):
            reasons.append(f"lon/lat: ({lon!r}, {lat!r}) is not a position")
            rec["lon"] = rec["lat"] = None
    _sanitize_floats(rec, reasons)
    p = rec.get("fix_period_s")
    if p is not None and not (finite(p) and 0.0 < p <= MAX_FIX_PERIOD_S):
        reasons.append(f"fix_period_s: {p!r} is not a fix period")
        rec["fix_period_s"] = None
    fq = rec.get("fix_quality", 0)
    if type(fq) is not int or not 0 <= fq <= 32767:
        reasons.append(f"fix_quality: {fq!r} is not a GGA quality")
        rec["fix_quality"] = 0
    _sanitize_ids(rec, reasons)
    b = rec.get("queue_backlog", 0)
    if type(b) is not int or not 0 <= b <= INT4_MAX:
        rec["queue_backlog"] = min(max(int(b), 0), INT4_MAX) if finite(b) else 0
    if reasons:
        alarms = [a for a in rec.get("alarms") or [] if a in ALARMS]
        if "invalid_value" not in alarms:
            alarms.append("invalid_value")
        rec["alarms"] = alarms
    return reasons


STREAM_RE = re.compile(r"^[0-9A-Za-z_-]{1,32}$")


def new_stream_id() -> str:
    """A random stream id (128 bits): unique per queue, without any registry."""
    return uuid.uuid4().hex


def telemetry_batch_json(stream: str, stream_start: int, records_json: list[str]) -> bytes:
    """A format 2 batch from records already serialised (the queue stores JSON text).

    ``stream_start`` is the stream's first seq: the server starts the stream's
    acknowledgement just below it (an older queue migrated to streams goes on
    numbering where it was)."""
    head = (
        f'{{"format":{TELEMETRY_FORMAT_VERSION},"stream":"{stream}",'
        f'"stream_start":{int(stream_start)},"records":['
    )
    return (head + ",".join(records_json) + "]}").encode()


@dataclass
class TelemetryAck:
    """Server -> agent: everything up to ``acked_seq`` of ``stream`` is stored (or rejected for
    good); rejected records with reasons.

    ``stream_conflict``: seqs of this batch are already stored on this stream with
    different content (the queue's numbering went backwards: restored or cloned
    state). Nothing from there on was stored; the agent must continue on a new
    stream (``TelemetryQueue.new_stream``). ``stream`` and ``stream_conflict`` are
    sent to format 2 agents only (a format 1 agent would not know them).
    """

    machine_id: int
    acked_seq: int
    stored: int = 0
    duplicates: int = 0
    rejected: list[dict[str, Any]] = field(default_factory=list)  # {"seq": n, "reason": "..."}
    stream: str = ""
    stream_conflict: bool = False
    # stored, but with a warning ({"seq": n, "reason": "..."}): e.g. dated too far back
    flagged: list[dict[str, Any]] = field(default_factory=list)

    @classmethod
    def from_dict(cls, obj: dict[str, Any]) -> TelemetryAck:
        """Parse an ack, ignoring fields a newer server may add."""
        return cls(**{k: v for k, v in obj.items() if k in _ACK_FIELDS})


_ACK_FIELDS = frozenset(f.name for f in fields(TelemetryAck))


def telemetry_topic(machine_id: int) -> str:
    """MQTT topic a machine publishes its telemetry batches on."""
    return f"fieldrx/machines/{machine_id}/telemetry"


def ack_topic(machine_id: int) -> str:
    """MQTT topic the server publishes ``TelemetryAck`` on for one machine."""
    return f"fieldrx/machines/{machine_id}/ack"


def jobs_topic(machine_id: int) -> str:
    """MQTT topic reserved for job notifications to one machine (readable by it only)."""
    return f"fieldrx/machines/{machine_id}/jobs"


def mqtt_username(machine_id: int) -> str:
    """A machine's MQTT user name; its password is the machine's current device token."""
    return f"machine-{machine_id}"


def mqtt_client_id(machine_id: int) -> str:
    """The one MQTT client id the broker accepts from the machine's user (so it cannot take
    over, and disconnect, a worker's or another machine's session by reusing its id)."""
    return f"fieldrx-edge-{machine_id}"
