"""NMEA-0183 parsing into one ``Fix`` per receiver epoch.

Receivers send several sentences per epoch (RMC, GGA, GNS, VTG, ...) from any
talker (GP, GN, GL, GA, GB, BD, GQ, GI, IN for integrated navigation, ...):
the talker names the source, not the meaning, so every talker is accepted (as
gpsd does) and counted in ``ParseStats.talkers``. Seed 001 only uses $GPRMC;
FieldRx also takes GGA and GNS for fix quality and HDOP, VTG for speed when RMC
has none, and ZDA for the date. Sentences of one epoch share the UTC time
field; VTG has none and joins the open epoch; a no-fix sentence with an empty
time field (receivers starting up send ``$GPRMC,,V,,,,,,,,,,N``) joins the
open epoch unless that epoch already has one of its type. An epoch is emitted
as soon as every type seen in the previous epochs has arrived (no extra
latency), or when the next epoch starts.

What counts as a fix follows a careful receiver parser (gpsd): RMC status A
and FAA mode not N, GGA quality > 0, GNS with at least one mode letter other
than N; a latitude/longitude outside ±90°/±180° or with minutes >= 60 is not a
position (``out_of_range``), and the epoch that carried it is not a fix.
Non-finite numbers (``nan``, ``inf``, ``1e999``) are treated as missing and
counted (``non_finite``), so a fix never carries one.

A line may carry binary bytes (UBX, RTCM) in front of or behind a sentence
when a receiver mixes protocols on one port; the parser resynchronises on
``$`` and counts the lines it had to resync (``resync``). Bad checksums and garbage are
counted and skipped, never raised: a receiver on a noisy serial line must not
stop the metering loop.
"""

from __future__ import annotations

import calendar
import datetime as dt
import math
from dataclasses import dataclass, field

import pynmea2

KNOT_M_S = 1852.0 / 3600.0
# GNS mode letters, best first, as the GGA quality they mean (NMEA 4.10 table
# for GNS field 6): R RTK fixed, F RTK float, P precise, D differential,
# A autonomous, E estimated (dead reckoning), M manual, S simulator; N none.
_GNS_QUALITY = (("R", 4), ("F", 5), ("P", 3), ("D", 2), ("A", 1), ("E", 6), ("M", 7), ("S", 8))


class _OutOfRange(ValueError):
    """A field parsed but lies outside what the NMEA format allows."""


@dataclass(slots=True)
class Fix:
    """One receiver epoch with RMC, GGA, GNS and VTG of that epoch merged."""

    t: float | None = None  # unix time, s (None until a date is known)
    time_of_day_s: float | None = None
    lat: float | None = None
    lon: float | None = None
    fix_quality: int = 0  # GGA quality / GNS mode (RMC status A alone counts as 1)
    hdop: float | None = None
    n_sats: int | None = None
    altitude_m: float | None = None
    speed_m_s: float | None = None
    course_deg: float | None = None
    rmc_status: str | None = None
    talker: str = ""
    types: set[str] = field(default_factory=set)
    bad_position: bool = False  # a sentence of this epoch had an out-of-range position
    quality_from: str = ""  # the sentence type (GGA/GNS) that gave fix_quality, hdop, n_sats
    x: float | None = None  # UTM, filled by the pipeline
    y: float | None = None

    @property
    def valid(self) -> bool:
        """A usable fix: a position, none rejected, RMC status A (if RMC seen), quality > 0."""
        if self.lat is None or self.lon is None or self.bad_position:
            return False
        if self.rmc_status is not None and self.rmc_status != "A":
            return False
        return self.fix_quality > 0


@dataclass
class ParseStats:
    """Counters a replay or a live source reports."""

    lines: int = 0
    sentences: dict[str, int] = field(
        default_factory=lambda: {"RMC": 0, "GGA": 0, "GNS": 0, "VTG": 0}
    )
    talkers: dict[str, int] = field(default_factory=dict)
    other_sentences: int = 0
    bad_checksum: int = 0
    malformed: int = 0
    out_of_range: int = 0  # fields outside the format's range (lat > 90°, minutes >= 60, ...)
    non_finite: int = 0  # nan/inf numbers, treated as missing
    resync: int = 0  # lines whose sentences were recovered from among non-NMEA bytes
    fixes: int = 0
    no_fix: int = 0
    fix_quality: dict[int, int] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {
            "lines": self.lines,
            "sentences": dict(self.sentences),
            "talkers": dict(sorted(self.talkers.items())),
            "other_sentences": self.other_sentences,
            "bad_checksum": self.bad_checksum,
            "malformed": self.malformed,
            "out_of_range": self.out_of_range,
            "non_finite": self.non_finite,
            "resync": self.resync,
            "fixes": self.fixes,
            "no_fix": self.no_fix,
            "fix_quality": {str(k): v for k, v in sorted(self.fix_quality.items())},
        }


def _tod(v: str) -> float | None:
    """hhmmss[.ss] to seconds of the day; None when empty; raises when not a time."""
    if not v:
        return None
    if len(v) < 6 or not v[:6].isdigit():
        raise ValueError(v)
    h, m, s = int(v[0:2]), int(v[2:4]), float(v[4:])
    if h > 23 or m > 59 or not 0.0 <= s < 61.0:  # 60.x: leap second
        raise _OutOfRange(v)
    return h * 3600 + m * 60 + s


def _angle(v: str, hemi: str, deg_digits: int, limit: float, neg: str, pos: str) -> float:
    """ddmm.mmmm / dddmm.mmmm + hemisphere to signed degrees, range-checked."""
    if hemi != neg and hemi != pos:
        raise ValueError(hemi)
    mins = v[deg_digits:]
    if not v[:deg_digits].isdigit() or not mins[:2].isdigit():
        raise ValueError(v)
    m = float(mins)
    if not m < 60.0:  # also false for nan
        raise _OutOfRange(v)
    deg = int(v[:deg_digits]) + m / 60.0
    if deg > limit:
        raise _OutOfRange(v)
    return -deg if hemi == neg else deg


class NmeaParser:
    """Feed lines, get ``Fix`` objects; keeps ``stats``.

    ``max_hdop`` marks fixes with a worse HDOP as unusable (quality kept, but
    ``valid`` false through ``fix_quality`` 0), so the fix-loss policy applies.
    """

    def __init__(self, max_hdop: float | None = None) -> None:
        self.stats = ParseStats()
        self.max_hdop = max_hdop
        self._cur: Fix | None = None
        self._cur_key: str = ""
        self._cur_done = False
        self._expected: set[str] = set()
        self._prev_types: set[str] = set()
        self._date: tuple[int, int, int] | None = None
        self._handlers = {
            "RMC": self._rmc,
            "GGA": self._gga,
            "GNS": self._gns,
            "VTG": self._vtg,
        }

    def feed(self, line: str | bytes) -> list[Fix]:
        """Parse one line; returns the fixes completed by it (0, 1 or rarely 2)."""
        st = self.stats
        st.lines += 1
        if isinstance(line, bytes):
            line = line.decode("ascii", "replace")
        line = line.strip()
        if line[:1] == "$" and line[-3:-2] == "*" and line.find("$", 1) < 0:
            return self._sentence(line)  # the usual case: one clean sentence
        # Resynchronise: binary bytes (which may hold '$' too) around or between
        # sentences. Every '$' starts a candidate; one without a sentence header
        # (letters/digits then ',': GPRMC, PUBX, PSRF103) is noise; bytes after a
        # checksum are cut.
        parts: list[str] = []
        skipped = False
        start = line.find("$")
        if start != 0:
            skipped = True
        if start >= 0:
            for part in line[start + 1 :].split("$"):
                comma = part.find(",", 0, 11)
                if comma < 4 or not (part[:comma].isascii() and part[:comma].isalnum()):
                    skipped = True
                    continue
                star = part.find("*")
                if 0 <= star < len(part) - 3:
                    skipped = True
                    part = part[: star + 3]
                parts.append("$" + part)
        if not parts:
            st.malformed += 1  # empty line, or noise with no sentence in it
            return []
        if skipped:
            st.resync += 1
        out: list[Fix] = []
        for part in parts:
            out += self._sentence(part)
        return out

    def flush(self) -> list[Fix]:
        """Emit the open epoch (end of a log)."""
        out: list[Fix] = []
        if self._cur is not None and not self._cur_done:
            out.append(self._finish(self._cur))
        self._cur, self._cur_key, self._cur_done = None, "", False
        return out

    # -- internals ---------------------------------------------------------

    def _sentence(self, line: str) -> list[Fix]:
        """One '$...*hh' sentence: framing and checksum here, fields in the handlers.

        pynmea2 gives the checksum; its ``parse`` is not used on this path because it
        builds an object per sentence (about 40 % of the parse time), and the framing
        has to be done here anyway to resynchronise after binary bytes.
        """
        st = self.stats
        star = line.find("*")
        if star < 0 or len(line) - star != 3:
            st.malformed += 1  # truncated: the checksum never arrived (or garbage after it)
            return []
        body = line[1:star]
        try:
            if int(line[star + 1 :], 16) != pynmea2.NMEASentence.checksum(body):
                st.bad_checksum += 1
                return []
        except ValueError:
            st.malformed += 1
            return []
        d = body.split(",")
        head = d[0]
        if head[:1] == "P":
            st.other_sentences += 1  # proprietary ($Pmmm...): well framed, not ours
            return []
        if len(head) != 5 or not (head.isascii() and head.isalnum()):
            st.malformed += 1  # not a talker + sentence type
            return []
        kind = head[2:]
        handler = self._handlers.get(kind)
        if handler is None:
            if kind == "ZDA":
                self._zda(d[1:])
            st.other_sentences += 1
            return []
        talker = head[:2]
        st.talkers[talker] = st.talkers.get(talker, 0) + 1
        try:
            return handler(d[1:], talker)
        except _OutOfRange:
            st.out_of_range += 1
            return []
        except (IndexError, ValueError):
            st.malformed += 1
            return []

    def _num(self, s: str) -> float | None:
        """A numeric field; None when empty or not a number; non-finite counted and None."""
        if not s:
            return None
        try:
            v = float(s)
        except ValueError:
            return None
        if math.isfinite(v):
            return v
        self.stats.non_finite += 1
        return None

    def _position(self, d: list[str], i: int) -> tuple[float, float] | None:
        """Latitude/longitude at fields i..i+3; None when empty; raises when bad."""
        if not d[i] and not d[i + 2]:
            return None
        lat = _angle(d[i], d[i + 1], 2, 90.0, "S", "N")
        lon = _angle(d[i + 2], d[i + 3], 3, 180.0, "W", "E")
        return lat, lon

    def _checked_position(self, d: list[str], i: int) -> tuple[tuple[float, float] | None, bool]:
        """(position or None, rejected): an out-of-range position is counted, not raised."""
        try:
            return self._position(d, i), False
        except _OutOfRange:
            self.stats.out_of_range += 1
            return None, True

    def _open(self, key: str, kind: str) -> list[Fix]:
        """Make the epoch this sentence belongs to current; returns the epoch it closes."""
        cur = self._cur
        if cur is not None:
            if key and key == self._cur_key:
                return []  # same epoch (or a late sentence of an emitted one)
            if not self._cur_done and kind not in cur.types and (not key or not self._cur_key):
                # an untimed sentence joins the open epoch; a timed one adopts an untimed epoch
                self._cur_key = self._cur_key or key
                return []
        out: list[Fix] = []
        if cur is not None:
            if not self._cur_done:
                out.append(self._finish(cur))
            # expect what the last two epochs had, so one lost GGA does not shrink the set;
            # VTG only where it is the epoch's speed (no RMC), so RMC epochs do not wait for it
            types = cur.types - {"VTG"} if "RMC" in cur.types else set(cur.types)
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
        if fx.fix_quality == 0 and fx.rmc_status == "A" and not fx.types & {"GGA", "GNS"}:
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

    def _epoch(
        self, d0: str, kind: str, talker: str, tod: float | None
    ) -> tuple[list[Fix], Fix | None]:
        """Open/join the epoch: (fixes it closed, the epoch to fill or None if already emitted)."""
        self.stats.sentences[kind] += 1
        out = self._open(d0, kind)
        fx = self._cur
        assert fx is not None
        if self._cur_done:
            return out, None  # late sentence of an epoch already emitted
        fx.types.add(kind)
        fx.talker = fx.talker or talker
        if tod is not None and fx.time_of_day_s is None:
            fx.time_of_day_s = tod
        return out, fx

    def _set_position(self, fx: Fix, pos: tuple[float, float] | None, rejected: bool) -> None:
        # first sentence of the epoch wins (all talkers report the same solution)
        if rejected:
            fx.bad_position = True
        elif pos is not None and fx.lat is None:
            fx.lat, fx.lon = pos

    def _rmc(self, d: list[str], talker: str) -> list[Fix]:
        tod = _tod(d[0])
        status = d[1]
        if status not in ("A", "V"):
            raise ValueError(status)
        pos, rejected = self._checked_position(d, 2)
        if len(d) > 8 and len(d[8]) == 6 and d[8].isdigit():
            try:
                day, mon, yy = int(d[8][0:2]), int(d[8][2:4]), int(d[8][4:6])
                year = 2000 + yy if yy < 80 else 1900 + yy
                dt.date(year, mon, day)
                self._date = (year, mon, day)
            except ValueError:
                self.stats.out_of_range += 1
        # NMEA 2.3+ FAA mode: N = data not valid even under status A (gpsd)
        if status == "A" and len(d) > 11 and d[11][:1] == "N":
            status = "V"
        out, fx = self._epoch(d[0], "RMC", talker, tod)
        if fx is None:
            return out
        first = fx.rmc_status is None  # the first RMC gives speed and course, even after VTG
        if first or status == "V":
            fx.rmc_status = status  # any RMC of the epoch saying V makes it no fix
        self._set_position(fx, pos, rejected)
        self._speed(fx, self._num(d[6]), KNOT_M_S, first)
        self._course(fx, d[7], first)
        return out + self._maybe_done()

    def _speed(self, fx: Fix, v: float | None, unit: float, override: bool) -> None:
        if v is not None and (override or fx.speed_m_s is None):
            if v >= 0.0:
                fx.speed_m_s = v * unit
            else:
                self.stats.out_of_range += 1

    def _course(self, fx: Fix, v: str, override: bool) -> None:
        course = self._num(v)
        if course is not None and (override or fx.course_deg is None):
            if 0.0 <= course <= 360.0:
                fx.course_deg = course
            else:
                self.stats.out_of_range += 1

    def _fix_data(self, fx: Fix, kind: str, qual: int, sats: str, hdop_s: str, alt_s: str) -> None:
        """Quality, satellites, HDOP, altitude of GGA/GNS; the epoch's first such sentence wins."""
        if fx.quality_from:
            return
        fx.quality_from = kind
        fx.fix_quality = qual
        fx.n_sats = int(sats) if sats.isdigit() else None
        hdop = self._num(hdop_s)
        if hdop is not None and hdop < 0.0:
            self.stats.out_of_range += 1
            hdop = None
        fx.hdop = hdop
        fx.altitude_m = self._num(alt_s)

    def _gga(self, d: list[str], talker: str) -> list[Fix]:
        tod = _tod(d[0])
        q = d[5]
        if q and not q.isdigit():
            raise ValueError(q)
        qual = int(q) if q else 0
        if qual > 9:
            raise _OutOfRange(q)
        pos, rejected = self._checked_position(d, 1)
        out, fx = self._epoch(d[0], "GGA", talker, tod)
        if fx is None:
            return out
        self._set_position(fx, pos, rejected)
        self._fix_data(fx, "GGA", qual, d[6], d[7], d[8] if len(d) > 8 else "")
        return out + self._maybe_done()

    def _gns(self, d: list[str], talker: str) -> list[Fix]:
        tod = _tod(d[0])
        mode = d[5]
        qual = 0
        for letter, q in _GNS_QUALITY:
            if letter in mode:
                qual = q
                break
        pos, rejected = self._checked_position(d, 1)
        out, fx = self._epoch(d[0], "GNS", talker, tod)
        if fx is None:
            return out
        self._set_position(fx, pos, rejected)
        self._fix_data(fx, "GNS", qual, d[6], d[7], d[8] if len(d) > 8 else "")
        return out + self._maybe_done()

    def _vtg(self, d: list[str], talker: str) -> list[Fix]:
        self.stats.sentences["VTG"] += 1
        if self._cur is None or self._cur_done:
            return []  # no open epoch: the speed is already in RMC of that epoch
        fx = self._cur
        fx.types.add("VTG")
        # NMEA 2.3+: course T, M, speed knots N, km/h K, mode; old format lacks the letters.
        if len(d) > 8 and d[8][:1] == "N":
            return self._maybe_done()  # mode N: not valid (gpsd ignores it too)
        self._speed(fx, self._num(d[6]) if len(d) > 6 else None, 1.0 / 3.6, False)
        self._course(fx, d[0], False)
        return self._maybe_done()

    def _zda(self, d: list[str]) -> None:
        """ZDA: time, day, month, year; gives GGA/GNS-only receivers a date."""
        try:
            day, mon, year = int(d[1]), int(d[2]), int(d[3])
            dt.date(year, mon, day)
        except (IndexError, ValueError):
            return
        self._date = (year, mon, day)
