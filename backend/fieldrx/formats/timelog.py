"""ISO 11783-10 TimeLogs in: TLGxxxxx.XML header + .BIN records -> as-applied arrays.

The header is a ``TIM`` whose attributes and ``PTN``/``DLV`` children with an
empty value say what each binary record carries (ISO 11783-10 Annex D), all
little-endian:

* uint32 ms since midnight, uint16 days since 1980-01-01 (TIM A empty);
* PTN: A int32 north and B int32 east (1e-7 degree), C int32 up (mm),
  D uint8 status, E uint16 PDOP, F uint16 HDOP (0.1), G uint8 satellites,
  H uint32 GPS UTC time (ms), I uint16 GPS UTC date, each only when the
  attribute is present and empty (a value in the header is a constant);
* uint8 number of values n, then n x (uint8 DLV index, int32 value).

Values keep the last reported value of each DLV (terminals log on change).
The DDIs FieldRx uses: 7 actual mass per area (mg/m^2 -> kg/ha x 0.01),
6 setpoint mass per area, 397 actual speed (mm/s), 141 actual work state
(1 = on), 67 actual working width (mm). Everything else is counted and
reported as ignored.
"""

from __future__ import annotations

import datetime as dt
import struct
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fieldrx.formats import FormatError
from fieldrx.formats.archive import parse_xml

EPOCH_1980 = dt.datetime(1980, 1, 1, tzinfo=dt.UTC)
PTN_FIELDS = (("A", "<i"), ("B", "<i"), ("C", "<i"), ("D", "<B"), ("E", "<H"), ("F", "<H"),
              ("G", "<B"), ("H", "<I"), ("I", "<H"))  # fmt: skip
MAX_RECORDS = 5_000_000
USED = {7: "applied", 6: "target", 397: "speed", 141: "work_state", 67: "width"}


@dataclass
class TimeLog:
    """Decoded records (time order as logged); NaN where a value was never reported."""

    name: str
    t: np.ndarray  # epoch seconds
    lat: np.ndarray
    lon: np.ndarray
    status: np.ndarray
    values: dict[int, np.ndarray]  # DDI -> raw values (last reported, NaN before the first)
    ignored_ddis: list[int] = field(default_factory=list)
    reported: dict[int, int] = field(default_factory=dict)  # DDI -> records reporting it

    def __len__(self) -> int:
        return len(self.t)

    def total(self, ddi: int) -> float | None:
        """What a total counter (yield, fuel ...) grew by over the log: the sum of its
        increases between records, so a counter reset (a drop) is not subtracted."""
        v = self.values.get(ddi)
        if v is None:
            return None
        f = v[np.isfinite(v)]
        return float(np.clip(np.diff(f), 0, None).sum()) if len(f) else None

    def series(self, ddi: int, scale: float = 1.0) -> np.ndarray:
        v = self.values.get(ddi)
        return np.full(len(self), np.nan) if v is None else v * scale


def read_timelog(name: str, header: bytes, data: bytes) -> TimeLog:
    """Decode ``name``.XML + ``name``.BIN (see module docstring); errors name the file."""
    xml_name, bin_name = f"{name}.XML", f"{name}.BIN"
    tim = parse_xml(header, xml_name)
    if tim.tag != "TIM":
        raise FormatError(f"{xml_name}: root element is {tim.tag}, not TIM")
    if tim.get("A") != "":
        raise FormatError(f"{xml_name}: TIM A must be empty (times in the binary)")
    ptn = tim.find("PTN")
    pos_fields = [] if ptn is None else [(k, f) for k, f in PTN_FIELDS if ptn.get(k) == ""]
    dlvs: list[int] = []
    for k, d in enumerate(tim.findall("DLV")):
        try:
            dlvs.append(int(d.get("A", ""), 16))
        except ValueError:
            raise FormatError(f"{xml_name} DLV[{k}]: DDI {d.get('A')!r} is not hex") from None
    rows_t: list[float] = []
    rows_pos: list[dict[str, Any]] = []
    last = np.full(len(dlvs), np.nan)
    counts = np.zeros(len(dlvs), dtype=np.int64)
    vals: list[np.ndarray] = []
    i, n = 0, len(data)
    while i < n:
        if len(rows_t) >= MAX_RECORDS:
            raise FormatError(f"{bin_name}: more than {MAX_RECORDS} records")
        try:
            ms, days = struct.unpack_from("<IH", data, i)
            i += 6
            pos: dict[str, Any] = {}
            for key, fmt in pos_fields:
                (pos[key],) = struct.unpack_from(fmt, data, i)
                i += struct.calcsize(fmt)
            (count,) = struct.unpack_from("<B", data, i)
            i += 1
            for _ in range(count):
                idx, v = struct.unpack_from("<Bi", data, i)
                i += 5
                if idx >= len(dlvs):
                    raise FormatError(
                        f"{bin_name} record {len(rows_t)}: DLV index {idx} but {xml_name} "
                        f"declares {len(dlvs)}"
                    )
                last[idx] = v
                counts[idx] += 1
        except struct.error:
            raise FormatError(
                f"{bin_name}: record {len(rows_t)} is cut short at byte {i} of {n} "
                f"(does {xml_name} describe this binary?)"
            ) from None
        rows_t.append((EPOCH_1980 + dt.timedelta(days=days, milliseconds=ms)).timestamp())
        rows_pos.append(pos)
        vals.append(last.copy())
    m = np.asarray(vals) if vals else np.zeros((0, len(dlvs)))

    def pos_col(key: str, scale: float) -> np.ndarray:
        if ptn is None:
            return np.full(len(rows_t), np.nan)
        if ptn.get(key) not in (None, ""):
            return np.full(len(rows_t), float(ptn.get(key, "nan")))
        return np.asarray([p.get(key, np.nan) for p in rows_pos], dtype=float) * scale

    values = {ddi: m[:, k] for k, ddi in enumerate(dlvs)}
    return TimeLog(
        name=name,
        t=np.asarray(rows_t, dtype=float),
        lat=pos_col("A", 1e-7),
        lon=pos_col("B", 1e-7),
        status=pos_col("D", 1.0),
        values=values,
        ignored_ddis=sorted({d for d in dlvs if d not in USED}),
        reported={d: int(counts[k]) for k, d in enumerate(dlvs)},
    )


def _totals(log: TimeLog) -> dict[str, Any]:
    """Growth of each total counter the log carries (ISO 11783-11 "Total ..." DDIs)."""
    from isoxml.models.ddi_entities import DDEntity

    out: dict[str, Any] = {}
    for ddi in sorted(log.values):
        try:
            d = DDEntity.from_id(ddi)
        except KeyError:
            continue
        if "Total" in d.name:
            out[str(ddi)] = {"name": d.name, "unit": d.unit, "total": log.total(ddi)}
    return out


def timelog_summary(log: TimeLog) -> dict[str, Any]:
    """What a log holds and what FieldRx can make of it (the imports' previews)."""
    pos = np.isfinite(log.lat) & np.isfinite(log.lon)
    widths = log.series(67, 0.001)
    applied = log.series(7, 0.01)
    has_rate = bool(np.isfinite(applied).any())
    centre = None
    if pos.any():
        centre = [float(np.median(log.lon[pos])), float(np.median(log.lat[pos]))]
    if has_rate:
        gives = "an as-applied map and application accuracy against a prescription (DDI 7)"
    else:
        gives = (
            "a coverage map (positions"
            + (", work state DDI 141" if 141 in log.values else "")
            + ") only: no applied rate (DDI 7), so no application accuracy"
        )
    return {
        "timelog": log.name,
        "records": len(log),
        "with_position": int(pos.sum()),
        "first_t": None if not len(log) else float(log.t.min()),
        "last_t": None if not len(log) else float(log.t.max()),
        "centre": centre,
        "ddis_used": sorted(d for d in log.values if d in USED),
        "ddis_ignored": log.ignored_ddis,
        "reported": {str(d): n for d, n in sorted(log.reported.items())},
        "totals": _totals(log),
        "has_rate": has_rate,
        "gives": gives,
        "mean_applied_rate_kg_ha": float(np.nanmean(applied)) if has_rate else None,
        "logged_width_m": None if not np.isfinite(widths).any() else float(np.nanmedian(widths)),
    }
