"""One stored telemetry record as a typed row: the ``telemetry`` COPY columns, stated once.

The field order is the COPY column order; ``TELEMETRY_COPY`` pairs each field with
its binary COPY type (the one codec, ``fieldrx.store.codec``). ``t`` goes as int8
microseconds since 2000-01-01 (the binary form of timestamptz, without building
a datetime per record) and ``geom`` as raw EWKB bytes (geometry_recv reads EWKB).
Readers use the names (``row.speed_m_s``), never an index.
"""

from __future__ import annotations

import struct
from typing import Any, NamedTuple

from fieldrx_edge.protocol import EXTRA_FIELDS

from fieldrx.store.codec import CopySpec

PG_EPOCH = 946684800.0  # 2000-01-01T00:00:00Z in Unix seconds
EWKB_POINT = struct.Struct("<BIIdd")  # little endian, Point with SRID flag, SRID, x, y


class TelemetryRow(NamedTuple):
    machine_id: int
    seq: int
    t: int  # microseconds since 2000-01-01 UTC
    job_id: int | None
    geom: bytes | None  # EWKB point (SRID 4326)
    fix_quality: int
    hdop: float | None
    speed_raw_m_s: float | None
    speed_filtered_m_s: float | None
    heading_deg: float | None
    cell_seq: int | None
    target_rate_kg_ha: float | None
    applied_rate_kg_ha: float | None
    target_shaft_rpm: float | None
    actual_shaft_rpm: float | None
    duty: float | None
    ndvi: float | None
    depth_mm: float | None
    implement_down: bool
    alarms: list[str]
    queue_backlog: int
    fix_period_s: float | None
    stream: str
    # optional sensor-job fields (protocol.EXTRA_FIELDS), last
    ndvi_raw: float | None = None
    actuator_mm: float | None = None
    gain_kp: float | None = None
    gain_ki: float | None = None
    gain_kd: float | None = None

    @property
    def t_s(self) -> float:
        """Record time, Unix seconds."""
        return self.t / 1e6 + PG_EPOCH

    @property
    def speed_m_s(self) -> float | None:
        """The filtered speed, or the raw one when the agent sent no filtered speed."""
        return (
            self.speed_filtered_m_s if self.speed_filtered_m_s is not None else self.speed_raw_m_s
        )

    @property
    def lonlat(self) -> tuple[float | None, float | None]:
        if self.geom is None:
            return None, None
        _, _, _, lon, lat = EWKB_POINT.unpack(self.geom)
        return lon, lat


_COPY_TYPE: dict[str, str] = {
    "machine_id": "int4",
    "seq": "int8",
    "t": "int8",
    "job_id": "int4",
    "geom": "bytea",
    "fix_quality": "int2",
    "cell_seq": "int4",
    "implement_down": "bool",
    "alarms": "varchar[]",
    "queue_backlog": "int4",
    "stream": "varchar",
}  # fmt: skip  (every other column is float8)

TELEMETRY_COPY = CopySpec(
    "telemetry",
    TelemetryRow._fields,
    tuple(_COPY_TYPE.get(f, "float8") for f in TelemetryRow._fields),
)
N_EXTRAS = len(EXTRA_FIELDS)
assert TelemetryRow._fields[-N_EXTRAS:] == EXTRA_FIELDS, "extras last, in protocol order"


def ewkb_point(lon: float, lat: float) -> bytes:
    return EWKB_POINT.pack(1, 0x20000001, 4326, lon, lat)


def make_row(*values: Any) -> TelemetryRow:
    """A row from values in column order (no per-field keyword parsing)."""
    return tuple.__new__(TelemetryRow, values)
