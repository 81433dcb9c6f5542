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

Only the standard library is used here, so the server and the agent share it
without pulling each other's dependencies.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import uuid
from dataclasses import asdict, dataclass, field, fields
from typing import Any, TypeGuard

from fieldrx_edge.jobkinds.registry import DEFAULT_KIND
from fieldrx_edge.jobkinds.registry import names as kind_names

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


def _canonical(obj: Any) -> bytes:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=False).encode()


@dataclass
class ControllerSettings:
    """Which motor controller the agent runs and with what parameters."""

    name: str = "ladrc"  # pid | incremental_pid | ladrc | fuzzy_pid
    params: dict[str, float] = field(default_factory=dict)
    period_s: float = 0.01  # motor loop period (100 Hz)


@dataclass
class JobPackage:
    """A job as the tractor downloads and caches it.

    ``corners_utm`` and ``corners_wgs84`` are flat lists of 8 numbers per cell
    (x0 y0 x1 y1 x2 y2 x3 y3, counter-clockwise, seed 001 Table 1), in the same
    path order as ``seq``. ``boundary_utm`` is the field boundary as GeoJSON
    Polygon/MultiPolygon coordinates in the field's UTM zone (holes included):
    the agent never applies outside it.

    The four corners are the cell's unclipped implement footprint (Table 1). At
    the field edge, around holes and in headland rings the real cell (clipped
    to the field, or between two offset curves) differs from it, and the
    rectangles of neighbouring cells overlap. Such cells also carry their real
    shape, as ragged rings in UTM, so the agent locates points in the cells the
    server planned and reports on (interior cells carry nothing extra):

    * ``shape_seq``: seq of each shaped cell, in path order (m cells);
    * ``shape_ring_offsets``: m + 1 offsets into the ring list; cell k's rings
      are rings ``shape_ring_offsets[k]:shape_ring_offsets[k + 1]`` (outer
      rings and holes alike: a point is in the cell by even-odd over all rings);
    * ``shape_offsets``: R + 1 offsets into the vertex list; ring r's vertices
      are ``shape_xy_utm[2 * shape_offsets[r]:2 * shape_offsets[r + 1]]`` as
      x y pairs, open (the first vertex is not repeated), at least 3 each.

    The shape fields are optional: a package without them (every older
    package) loads unchanged and keeps its checksum, because empty shape fields
    are left out of the canonical JSON; when present, the checksum covers them.
    """

    job_id: int
    machine_id: int
    prescription_id: int
    prescription_version: int
    field_name: str
    utm_epsg: int
    implement_width_m: float
    lag_s: float
    calibration: dict[str, Any]
    controller: ControllerSettings
    boundary_utm: dict[str, Any]
    seq: list[int]
    swath: list[int]
    rate_kg_ha: list[float]
    corners_utm: list[float]
    corners_wgs84: list[float]
    antenna_forward_m: float = 0.0  # outlet position relative to the GNSS antenna
    antenna_lateral_m: float = 0.0
    speed_min_m_s: float = 0.8
    speed_max_m_s: float = 2.5
    fix_loss_hold_s: float = 2.0  # hold the last rate this long after losing fix, then stop
    overlap_control: bool = True
    product: str = ""
    shape_seq: list[int] = field(default_factory=list)
    shape_ring_offsets: list[int] = field(default_factory=list)
    shape_offsets: list[int] = field(default_factory=list)
    shape_xy_utm: list[float] = field(default_factory=list)
    # job kind: one of fieldrx_edge.jobkinds.registry's; kind_settings are the kind's
    # validated settings (fieldrx_edge.jobkinds). Both are left out of the canonical JSON
    # when default, so prescription-map packages keep their bytes and checksum.
    kind: str = DEFAULT_KIND
    kind_settings: dict[str, Any] = field(default_factory=dict)
    # the unit of ``rate_kg_ha`` ("kg/ha", or "l/ha" for a liquid product's volume
    # prescription) and the product's density in kg/l (0: not known). They travel with the
    # product so an ISOBUS TC converts between mass (DDI 6) and volume (DDI 1) implements
    # without a number typed in the cab; left out of the canonical JSON when default.
    rate_unit: str = "kg/ha"
    product_density_kg_l: float = 0.0
    format_version: int = FORMAT_VERSION
    checksum: str = ""

    @property
    def n_cells(self) -> int:
        return len(self.seq)

    def _body(self) -> dict[str, Any]:
        """Fields as a dict, without the checksum. Lists are shared, not copied (asdict would
        deep-copy ~1.6 M numbers for a 100k-cell job)."""
        body = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "checksum"}
        body["controller"] = asdict(self.controller)
        if not self.shape_seq:  # optional: absent shapes keep older packages' bytes and checksum
            for name in SHAPE_FIELDS:
                del body[name]
        if self.kind == DEFAULT_KIND and not self.kind_settings:
            del body["kind"], body["kind_settings"]
        if self.rate_unit == "kg/ha" and not self.product_density_kg_l:
            del body["rate_unit"], body["product_density_kg_l"]
        return body

    def cell_shapes(self) -> dict[int, list[list[float]]]:
        """Shaped cells: path index -> rings, each a flat x y list in UTM (see class doc)."""
        if not self.shape_seq:
            return {}
        index = {s: i for i, s in enumerate(self.seq)}
        ro, vo, xy = self.shape_ring_offsets, self.shape_offsets, self.shape_xy_utm
        out: dict[int, list[list[float]]] = {}
        for k, s in enumerate(self.shape_seq):
            out[index[s]] = [xy[2 * vo[r] : 2 * vo[r + 1]] for r in range(ro[k], ro[k + 1])]
        return out

    def compute_checksum(self) -> str:
        return hashlib.sha256(_canonical(self._body())).hexdigest()

    def seal(self) -> JobPackage:
        """Validate and set the checksum; returns self for chaining."""
        self.validate()
        self.checksum = self.compute_checksum()
        return self

    def validate(self) -> None:
        n = len(self.seq)
        for name, got, want in (
            ("swath", len(self.swath), n),
            ("rate_kg_ha", len(self.rate_kg_ha), n),
            ("corners_utm", len(self.corners_utm), 8 * n),
            ("corners_wgs84", len(self.corners_wgs84), 8 * n),
        ):
            if got != want:
                raise ProtocolError(f"job package: {name} has {got} values, expected {want}")
        self._validate_shapes()
        if self.kind not in kind_names():
            raise ProtocolError(
                f"job package: kind {self.kind!r} is not one of {list(kind_names())}"
            )
        if not isinstance(self.kind_settings, dict):
            raise ProtocolError("job package: kind_settings must be an object")
        if self.implement_width_m <= 0:
            raise ProtocolError("job package: implement_width_m must be positive")
        if self.rate_unit not in ("kg/ha", "l/ha"):
            raise ProtocolError(f"job package: rate_unit {self.rate_unit!r} is not kg/ha or l/ha")
        d = self.product_density_kg_l
        if not math.isfinite(d) or (d and not 0.05 <= d <= 5.0):
            raise ProtocolError(
                f"job package: product_density_kg_l {d!r} must be 0 (unknown) or 0.05-5 kg/l"
            )
        if self.lag_s < 0:
            raise ProtocolError("job package: lag_s must not be negative")
        for i, r in enumerate(self.rate_kg_ha):
            if not math.isfinite(r) or r < 0:
                raise ProtocolError(f"job package: cell {self.seq[i]} has invalid rate {r!r}")

    def _validate_shapes(self) -> None:
        m = len(self.shape_seq)
        ro, vo, xy = self.shape_ring_offsets, self.shape_offsets, self.shape_xy_utm
        if m == 0:
            if ro or vo or xy:
                raise ProtocolError("job package: shape fields given without shape_seq")
            return
        known = set(self.seq)
        if len(set(self.shape_seq)) != m or any(s not in known for s in self.shape_seq):
            raise ProtocolError("job package: shape_seq must name distinct cells of seq")
        if len(ro) != m + 1 or ro[0] != 0 or any(b <= a for a, b in zip(ro, ro[1:], strict=False)):
            raise ProtocolError(
                f"job package: shape_ring_offsets must be {m + 1} increasing offsets from 0"
            )
        n_rings = ro[-1]
        if (
            len(vo) != n_rings + 1
            or vo[0] != 0
            or any(b - a < 3 for a, b in zip(vo, vo[1:], strict=False))
        ):
            raise ProtocolError(
                f"job package: shape_offsets must be {n_rings + 1} offsets from 0,"
                " at least 3 vertices per ring"
            )
        if len(xy) != 2 * vo[-1]:
            raise ProtocolError(
                f"job package: shape_xy_utm has {len(xy)} values, expected {2 * vo[-1]}"
            )
        if not all(math.isfinite(v) for v in xy):
            raise ProtocolError("job package: shape_xy_utm has a non-finite coordinate")

    def to_json(self) -> bytes:
        if not self.checksum:
            self.seal()
        return _canonical({**self._body(), "checksum": self.checksum})

    @classmethod
    def from_json(cls, data: bytes | str | dict[str, Any], verify: bool = True) -> JobPackage:
        """Parse a package; with ``verify`` the checksum must match the content."""
        obj = json.loads(data) if isinstance(data, bytes | str) else dict(data)
        version = obj.get("format_version")
        if version != FORMAT_VERSION:
            raise ProtocolError(
                f"job package: format_version {version!r} not supported (expected {FORMAT_VERSION})"
            )
        known = {f.name for f in fields(cls)}
        unknown = set(obj) - known
        if unknown:
            raise ProtocolError(f"job package: unknown fields {sorted(unknown)}")
        obj["controller"] = ControllerSettings(**obj.get("controller", {}))
        try:
            pkg = cls(**obj)
        except TypeError as exc:
            raise ProtocolError(f"job package: {exc}") from exc
        pkg.validate()
        if verify and pkg.checksum != pkg.compute_checksum():
            raise ProtocolError("job package: checksum does not match its content")
        return pkg


SHAPE_FIELDS = ("shape_seq", "shape_ring_offsets", "shape_offsets", "shape_xy_utm")

# Telemetry -----------------------------------------------------------------

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


def _finite(v: object) -> TypeGuard[float]:
    """A real, finite number (bool excluded); narrows ``v`` for the comparisons after it."""
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _sanitize_floats(rec: dict[str, Any], reasons: list[str]) -> None:
    """``sanitize_record``'s measured values: non-finite to null, out of range clamped,
    a heading wrapped into [0, 360)."""
    for name in _FLOAT_FIELDS:
        v = rec.get(name)
        if v is None:
            continue
        if not _finite(v):
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
    if not _finite(t) or t <= 0:
        return [f"drop: t {t!r} is not a positive finite unix time"]
    lon, lat = rec.get("lon"), rec.get("lat")
    if lon is not None or lat is not None:
        if not (_finite(lon) and _finite(lat) and -180.0 <= lon <= 180.0 and -90.0 <= lat <= 90.0):
            reasons.append(f"lon/lat: ({lon!r}, {lat!r}) is not a position")
            rec["lon"] = rec["lat"] = None
    _sanitize_floats(rec, reasons)
    p = rec.get("fix_period_s")
    if p is not None and not (_finite(p) and 0.0 < p <= MAX_FIX_PERIOD_S):
        reasons.append(f"fix_period_s: {p!r} is not a fix period")
        rec["fix_period_s"] = None
    fq = rec.get("fix_quality", 0)
    if type(fq) is not int or not 0 <= fq <= 32767:
        reasons.append(f"fix_quality: {fq!r} is not a GGA quality")
        rec["fix_quality"] = 0
    _sanitize_ids(rec, reasons)
    b = rec.get("queue_backlog", 0)
    if type(b) is not int or not 0 <= b <= INT4_MAX:
        rec["queue_backlog"] = min(max(int(b), 0), INT4_MAX) if _finite(b) else 0
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


def cell_batch_json(stream: str, stream_start: int, records_json: list[str]) -> bytes:
    """A cell batch (format 3, ``"kind": "cells"``) from records already serialised."""
    head = (
        f'{{"format":{CELL_FORMAT_VERSION},"kind":"cells","stream":"{stream}",'
        f'"stream_start":{int(stream_start)},"records":['
    )
    return (head + ",".join(records_json) + "]}").encode()


@dataclass(slots=True)
class CellRecord:
    """Uplink profile ``thin``: the as-applied figures of one cell, sent once the tractor has
    left it (and everything metered into it has landed: seed 001 eq. 16's lag).

    Computed on the tractor by the one as-applied kernel (``fieldrx_edge.asapplied``,
    seed 001 eq. 16-18) over the full 10 Hz log, which stays on the tractor, so the
    server's report from these records equals the report from the full log:

    * ``mass_g``: metered mass that landed in the cell (eq. 16-17: flow from the shaft
      speed over each fix period, landing T_lag later, antenna offset ahead); on the
      record with ``cell_seq`` null, the mass that landed in no cell;
    * ``driven_m``: the cell's driven length (eq. 17's v t, ``asapplied.driven_length``);
    * ``n_fixes``, ``worked_s``, ``t_entry``/``t_exit``, the means: the fixes whose own
      cell (the one the agent metered for) is this one, implement down; their fix
      periods, first/last fix time, mean speed and mean target/applied rate;
    * ``flags``: the alarms raised in those fixes.

    A cell can get more than one record (re-entered later, or a little mass landing
    after its record left): the server adds them up.
    """

    machine_id: int
    seq: int
    job_id: int
    t_entry: float
    t_exit: float
    cell_seq: int | None = None
    n_fixes: int = 0
    worked_s: float = 0.0
    mass_g: float = 0.0
    driven_m: float | None = None
    mean_speed_m_s: float | None = None
    mean_target_rate_kg_ha: float | None = None
    mean_applied_rate_kg_ha: float | None = None
    flags: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {f: getattr(self, f) for f in CELL_FIELDS}

    @classmethod
    def from_dict(cls, obj: dict[str, Any]) -> CellRecord:
        """Parse and validate one cell record; ``ProtocolError`` names the offending field."""
        if not isinstance(obj, dict):
            raise ProtocolError("cell record is not a JSON object")
        unknown = set(obj) - _CELL_FIELD_SET
        if unknown:
            raise ProtocolError(f"unknown fields {sorted(unknown)}")
        for name in ("machine_id", "seq", "job_id", "t_entry", "t_exit"):
            if name not in obj:
                raise ProtocolError(f"missing required field '{name}'")
        rec = cls(**obj)
        rec.validate()
        return rec

    def validate(self) -> None:
        for name in ("machine_id", "seq", "job_id"):
            v = getattr(self, name)
            if type(v) is not int or v < 1:
                raise ProtocolError(f"{name} must be a positive integer, got {v!r}")
        c = self.cell_seq
        if c is not None and (type(c) is not int or not -INT4_MAX <= c <= INT4_MAX):
            raise ProtocolError(f"cell_seq must be an integer or null, got {c!r}")
        if type(self.n_fixes) is not int or not 0 <= self.n_fixes <= INT4_MAX:
            raise ProtocolError(f"n_fixes must be a non-negative integer, got {self.n_fixes!r}")
        for name in ("t_entry", "t_exit"):
            v = getattr(self, name)
            if not _finite(v) or v <= 0:
                raise ProtocolError(f"{name} must be a positive unix time in seconds, got {v!r}")
        if self.t_exit < self.t_entry:
            raise ProtocolError(f"t_exit {self.t_exit!r} is before t_entry {self.t_entry!r}")
        for name in ("worked_s", "mass_g"):
            v = getattr(self, name)
            if not _finite(v) or v < 0:
                raise ProtocolError(f"{name} must be a finite number >= 0, got {v!r}")
        for name in _CELL_OPTIONAL:
            v = getattr(self, name)
            if v is not None and (not _finite(v) or v < 0):
                raise ProtocolError(f"{name} must be a finite number >= 0 or null, got {v!r}")
        if not isinstance(self.flags, list) or any(a not in ALARMS for a in self.flags):
            raise ProtocolError(f"flags must be a list of {list(ALARMS)}, got {self.flags!r}")


CELL_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(CellRecord))
_CELL_FIELD_SET = frozenset(CELL_FIELDS)
_CELL_OPTIONAL = (
    "driven_m", "mean_speed_m_s", "mean_target_rate_kg_ha", "mean_applied_rate_kg_ha",
)  # fmt: skip


def sanitize_cell_record(rec: dict[str, Any]) -> list[str]:
    """``sanitize_record`` for cell records (the queue runs it before storing one): they are
    computed by the agent itself, so anything wrong is a bug; say what, never block."""
    try:
        CellRecord.from_dict(rec).validate()
    except (ProtocolError, TypeError) as exc:
        return [f"drop: {exc}"]
    return []


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
