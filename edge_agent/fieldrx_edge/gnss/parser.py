"""NMEA-0183 parsing into one ``Fix`` per receiver epoch.

Receivers send several sentences per epoch (RMC, GGA, VTG, ...) from any
talker (GP, GN, GL, GA, BD). Seed 001 only uses $GPRMC; FieldRx also takes
GGA for fix quality and HDOP, and VTG for speed when RMC has none. Sentences of
one epoch share the UTC time field; VTG has none and joins the open epoch.
An epoch is emitted as soon as every timestamped type seen in the previous
epoch has arrived (no extra latency), or when the next epoch starts.

Bad checksums and garbage are counted and skipped, never raised: a receiver
on a noisy serial line must not stop the metering loop.
"""

from __future__ import annotations

import calendar
import datetime as dt
from dataclasses import dataclass, field

import pynmea2

KNOT_M_S = 1852.0 / 3600.0
TALKERS = frozenset({"GP", "GN", "GL", "GA", "BD", "GB", "GQ"})


@dataclass(slots=True)
class Fix:
    """One receiver epoch with RMC, GGA and VTG of that epoch merged."""

    t: float | None = None  # unix time, s (None until a date is known)
    time_of_day_s: float | None = None
    lat: float | None = None
    lon: float | None = None
    fix_quality: int = 0  # GGA quality (RMC status A alone counts as 1)
    hdop: float | None = None
    n_sats: int | None = None
    altitude_m: float | None = None
    speed_m_s: float | None = None
    course_deg: float | None = None
    rmc_status: str | None = None
    talker: str = ""
    types: set[str] = field(default_factory=set)
    x: float | None = None  # UTM, filled by the pipeline
    y: float | None = None

    @property
    def valid(self) -> bool:
        """A usable fix: a position, RMC status A (if RMC seen) and GGA quality > 0 (if seen)."""
        if self.lat is None or self.lon is None:
            return False
        if self.rmc_status is not None and self.rmc_status != "A":
            return False
        return self.fix_quality > 0


@dataclass
class ParseStats:
    """Counters a replay or a live source reports."""

    lines: int = 0
    sentences: dict[str, int] = field(default_factory=lambda: {"RMC": 0, "GGA": 0, "VTG": 0})
    other_sentences: int = 0
    bad_checksum: int = 0
    malformed: int = 0
    foreign_talker: int = 0
    fixes: int = 0
    no_fix: int = 0
    fix_quality: dict[int, int] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {
            "lines": self.lines,
            "sentences": dict(self.sentences),
            "other_sentences": self.other_sentences,
            "bad_checksum": self.bad_checksum,
            "malformed": self.malformed,
            "foreign_talker": self.foreign_talker,
            "fixes": self.fixes,
            "no_fix": self.no_fix,
            "fix_quality": {str(k): v for k, v in sorted(self.fix_quality.items())},
        }


def _f(s: str) -> float | None:
    try:
        return float(s) if s else None
    except ValueError:
        return None


def _latlon(v: str, hemi: str, deg_digits: int) -> float | None:
    """ddmm.mmmm / dddmm.mmmm to signed degrees."""
    if not v or len(v) < deg_digits + 2:
        return None
    try:
        deg = int(v[:deg_digits]) + float(v[deg_digits:]) / 60.0
    except ValueError:
        return None
    return -deg if hemi in ("S", "W") else deg


def _tod(v: str) -> float | None:
    if len(v) < 6:
        return None
    try:
        return int(v[0:2]) * 3600 + int(v[2:4]) * 60 + float(v[4:])
    except ValueError:
        return None


class NmeaParser:
    """Feed lines, get ``Fix`` objects; keeps ``stats``.

    ``max_hdop`` marks fixes with a worse HDOP as unusable (quality kept, but
    ``valid`` false through ``fix_quality`` 0), so the fix-loss policy applies.
    """

    def __init__(self, max_hdop: float | None = None) -> None:
        self.stats = ParseStats()
        self.max_hdop = max_hdop
        self._cur: Fix | None = None
        self._cur_key: str | None = None
        self._cur_done = False
        self._expected: set[str] = set()
        self._prev_types: set[str] = set()
        self._date: tuple[int, int, int] | None = None
        self._last_tod: float | None = None

    def feed(self, line: str | bytes) -> list[Fix]:
        """Parse one line; returns the fixes completed by it (0, 1 or rarely 2)."""
        st = self.stats
        st.lines += 1
        if isinstance(line, bytes):
            line = line.decode("ascii", "replace")
        line = line.strip()
        if not line:
            st.malformed += 1
            return []
        try:
            msg = pynmea2.parse(line, check=True)
        except pynmea2.ChecksumError as exc:
            if "missing" in str(exc):
                st.malformed += 1  # truncated: the checksum never arrived
            else:
                st.bad_checksum += 1
            return []
        except (pynmea2.ParseError, pynmea2.SentenceTypeError, ValueError, AttributeError):
            st.malformed += 1
            return []
        kind = getattr(msg, "sentence_type", None)
        if kind not in ("RMC", "GGA", "VTG"):
            st.other_sentences += 1
            return []
        talker = getattr(msg, "talker", "")
        if talker not in TALKERS:
            st.foreign_talker += 1
            return []
        d = msg.data
        try:
            if kind == "RMC":
                return self._rmc(d, talker)
            if kind == "GGA":
                return self._gga(d, talker)
            return self._vtg(d, talker)
        except (IndexError, ValueError):
            st.malformed += 1
            return []

    def flush(self) -> list[Fix]:
        """Emit the open epoch (end of a log)."""
        out: list[Fix] = []
        if self._cur is not None and not self._cur_done:
            out.append(self._finish(self._cur))
        self._cur, self._cur_key, self._cur_done = None, None, False
        return out

    # -- internals ---------------------------------------------------------

    def _open(self, key: str) -> list[Fix]:
        out: list[Fix] = []
        if self._cur_key == key and self._cur is not None:
            return out
        if self._cur is not None:
            if not self._cur_done:
                out.append(self._finish(self._cur))
            # expect what the last two epochs had, so one lost GGA does not shrink the set
            types = self._cur.types - {"VTG"}
            self._expected = types | self._prev_types
            self._prev_types = types
        self._cur = Fix()
        self._cur_key = key
        self._cur_done = False
        return out

    def _maybe_done(self) -> list[Fix]:
        cur = self._cur
        assert cur is not None
        if not self._cur_done and self._expected and self._expected <= cur.types:
            self._cur_done = True
            return [self._finish(cur)]
        return []

    def _finish(self, fx: Fix) -> Fix:
        st = self.stats
        if fx.fix_quality == 0 and fx.rmc_status == "A" and "GGA" not in fx.types:
            fx.fix_quality = 1
        if self.max_hdop is not None and fx.hdop is not None and fx.hdop > self.max_hdop:
            fx.fix_quality = 0
        if fx.time_of_day_s is not None and self._date is not None:
            y, m, dd = self._date
            fx.t = calendar.timegm((y, m, dd, 0, 0, 0)) + fx.time_of_day_s
        st.fixes += 1
        st.fix_quality[fx.fix_quality] = st.fix_quality.get(fx.fix_quality, 0) + 1
        if not fx.valid:
            st.no_fix += 1
        return fx

    def _rmc(self, d: list[str], talker: str) -> list[Fix]:
        tod = _tod(d[0])
        lat = _latlon(d[2], d[3], 2)
        lon = _latlon(d[4], d[5], 3)
        status = d[1]
        if tod is None or status not in ("A", "V"):
            self.stats.malformed += 1
            return []
        if len(d) > 8 and len(d[8]) == 6:
            try:
                day, mon, yy = int(d[8][0:2]), int(d[8][2:4]), int(d[8][4:6])
                dt.date(2000 + yy, mon, day)
                self._date = (2000 + yy if yy < 80 else 1900 + yy, mon, day)
            except ValueError:
                pass
        self.stats.sentences["RMC"] += 1
        out = self._open(d[0])
        fx = self._cur
        assert fx is not None
        if self._cur_done:
            return out  # late sentence of an epoch already emitted
        fx.types.add("RMC")
        fx.talker = fx.talker or talker
        fx.time_of_day_s = tod
        fx.rmc_status = status
        if lat is not None and lon is not None:
            fx.lat, fx.lon = lat, lon
        knots = _f(d[6])
        if knots is not None:
            fx.speed_m_s = knots * KNOT_M_S
        course = _f(d[7])
        if course is not None:
            fx.course_deg = course
        return out + self._maybe_done()

    def _gga(self, d: list[str], talker: str) -> list[Fix]:
        tod = _tod(d[0])
        try:
            qual = int(d[5]) if d[5] else 0
        except ValueError:
            qual = -1
        if tod is None or qual < 0:
            self.stats.malformed += 1
            return []
        self.stats.sentences["GGA"] += 1
        out = self._open(d[0])
        fx = self._cur
        assert fx is not None
        if self._cur_done:
            return out
        fx.types.add("GGA")
        fx.talker = fx.talker or talker
        fx.time_of_day_s = tod
        fx.fix_quality = qual
        lat = _latlon(d[1], d[2], 2)
        lon = _latlon(d[3], d[4], 3)
        if lat is not None and lon is not None and fx.lat is None:
            fx.lat, fx.lon = lat, lon
        fx.n_sats = int(d[6]) if d[6].isdigit() else None
        fx.hdop = _f(d[7])
        fx.altitude_m = _f(d[8]) if len(d) > 8 else None
        return out + self._maybe_done()

    def _vtg(self, d: list[str], talker: str) -> list[Fix]:
        self.stats.sentences["VTG"] += 1
        if self._cur is None or self._cur_done:
            return []  # no open epoch: the speed is already in RMC of that epoch
        fx = self._cur
        fx.types.add("VTG")
        # NMEA 2.3+: course T, M, speed knots N, km/h K; old format lacks the unit letters.
        course = _f(d[0])
        kmh = _f(d[6]) if len(d) > 6 else None
        if fx.speed_m_s is None and kmh is not None:
            fx.speed_m_s = kmh / 3.6
        if fx.course_deg is None and course is not None:
            fx.course_deg = course
        return []
