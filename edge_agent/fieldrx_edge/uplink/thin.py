"""Uplink profile ``thin``: a 1 Hz track plus one record per cell left, the 10 Hz log kept here.

A machine at 10 Hz sends 36,000 records an hour; the server stores, indexes and
reads each of them back for the report. With the thin profile the tractor sends
what the report needs instead:

* the track, one telemetry record per ``track_period_s`` (1 s): position, speed,
  rates, alarms for the live view, the alerts and the job map's track. These
  carry no ``cell_seq`` (the cell records count the cells, exactly) and their
  ``fix_period_s`` is the time they stand for;
* one ``cell_records.CellRecord`` per cell left, computed here by the one as-applied
  kernel (``fieldrx_edge.asapplied.records_applied``, seed 001 eq. 16-18: flow
  from the shaft speed over each fix period, landing T_lag later along the
  track, ``antenna_forward_m`` ahead, split among the cells' polygons) over the
  full log, so the server's report from cell records is the report it would
  compute from every fix (``CellAccumulator``);
* the full 10 Hz log stays on the tractor, one JSON-lines file per job
  (``RawLog``), uploaded as one gzip file when the office asks for it
  (``fieldrx-edge upload-log``).

Incremental, exactly: a fix's figures depend on itself, the next fix (its
period and the trapezoid of eq. 17) and the track up to its landing time
(eq. 16). ``CellAccumulator`` keeps a short window of the log and passes fixes
to the kernel once those are known, ``CHUNK`` at a time, so what it computes
does not depend on how the fixes arrived (one by one or in batches) and a
restarted agent replaying its raw log emits the same cell records in the same
order: it skips the ones its cell queue already holds (the count is stored in
the queue's transaction) and sends the rest, none twice and none lost.
"""

from __future__ import annotations

import gzip
import json
import logging
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fieldrx_edge.asapplied import (
    Cells,
    RecordColumns,
    driven_length,
    fix_periods,
    records_applied,
)
from fieldrx_edge.gnss.utm import UtmProjection
from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.locate import boundary_rings
from fieldrx_edge.metering import calibration_from_dict
from fieldrx_edge.protocol import MAX_FIX_PERIOD_S, UPLINK_PROFILES, sanitize_record
from fieldrx_edge.uplink.queue import TelemetryQueue

log = logging.getLogger(__name__)

CHUNK = 10  # fixes per kernel call (1 s at 10 Hz)
HOLD_S = 2.0  # a cell's record leaves once nothing has landed in it for this long
MAX_GAP_S = 2.0  # the report's (fleet.reports.MAX_GAP_S): a longer gap is an outage
TRACK_PERIOD_S = 1.0


def check_profile(profile: str) -> str:
    if profile not in UPLINK_PROFILES:
        raise ValueError(f"uplink profile {profile!r} is not one of {list(UPLINK_PROFILES)}")
    return profile


@dataclass
class _Bucket:
    """What one cell (or no cell: key -1) has gathered since its last record."""

    t_entry: float = float("inf")
    t_exit: float = float("-inf")
    touch_t: float = float("-inf")  # last fix that added anything
    n_fixes: int = 0
    worked_s: float = 0.0
    mass_g: float = 0.0
    speed_sum: float = 0.0
    target_sum: float = 0.0
    applied_sum: float = 0.0
    flags: set[str] = field(default_factory=set)
    span0: float = float("inf")  # times of fixes whose mass landed here (no own fix: spill)
    span1: float = float("-inf")


class CellAccumulator:
    """The as-applied kernel run over a job's 10 Hz log as it grows; cell records out.

    ``add(record)`` takes each fix's telemetry record (``runtime.make_record``)
    in time order and returns the cell records that became final;
    ``flush()`` returns the rest (end of the job).
    """

    def __init__(self, job: JobPackage) -> None:
        self.job = job
        self.cells = Cells.build(
            job.corners_utm,
            job.swath,
            job.cell_shapes(),
            [ring for ring, _ in boundary_rings(job.boundary_utm)],
        )
        self.driven = driven_length(self.cells)
        self.index = {int(s): i for i, s in enumerate(job.seq)}
        self.cal = calibration_from_dict(job.calibration) if job.calibration else None
        self.proj = UtmProjection(job.utm_epsg)
        self.width = job.implement_width_m
        # the window: columns of the fixes from the last positioned one before the first
        # unplaced fix on (interpolating a landing point needs the track point before it)
        self._cols: dict[str, list[Any]] = {k: [] for k in _COLS}
        self._dts: list[float] = []  # fix period of each fix whose successor is known
        self._placed = 0  # fixes of the window already given to the kernel
        self._settled = 0  # fixes of the window whose figures are known
        self._track_end = float("-inf")  # time of the newest positioned fix
        self._buckets: dict[int, _Bucket] = {}
        self._own_now = -1

    def add(self, rec: dict[str, Any]) -> list[dict[str, Any]]:
        c = self._cols
        t = float(rec["t"])
        x = y = float("nan")
        if rec.get("lon") is not None and rec.get("lat") is not None:
            x, y = self.proj.forward(rec["lon"], rec["lat"])
            self._track_end = max(self._track_end, t)
        cell = rec.get("cell_seq")
        v = rec.get("speed_filtered_m_s")
        v = rec.get("speed_raw_m_s") if v is None else v
        for key, val in (
            ("t", t),
            ("p", _num(rec.get("fix_period_s"))),
            ("x", x),
            ("y", y),
            ("h", _num(rec.get("heading_deg"))),
            ("rpm", _num(rec.get("actual_shaft_rpm"))),
            ("own", -1 if cell is None else self.index.get(int(cell), -1)),
            ("applied", rec.get("applied_rate_kg_ha") or 0.0),
            ("target", rec.get("target_rate_kg_ha") or 0.0),
            ("v", v or 0.0),
            ("down", bool(rec.get("implement_down"))),
            ("alarms", list(rec.get("alarms") or ())),
        ):
            c[key].append(val)
        n = len(c["t"])
        if n >= 2:  # the previous fix's period is known now (it needs the next fix's time)
            self._dts.append(
                float(fix_periods(np.asarray(c["t"][-2:]), np.asarray(c["p"][-2:]), MAX_GAP_S)[0])
            )
        lag = self.job.lag_s
        while (
            self._settled < len(self._dts)
            and self._track_end >= c["t"][self._settled] + self._dts[self._settled] + lag
        ):
            self._settled += 1
        out: list[dict[str, Any]] = []
        while self._settled - self._placed >= CHUNK:
            out.extend(self._place(self._placed + CHUNK))
        return out

    def flush(self) -> list[dict[str, Any]]:
        """Everything left (the job ended): the last fixes are placed with the track as it is."""
        out: list[dict[str, Any]] = []
        if len(self._cols["t"]) > self._placed:
            out.extend(self._place(len(self._cols["t"]), final=True))
        out.extend(self._emit(float("inf"), everything=True))
        return out

    def _place(self, upto: int, final: bool = False) -> list[dict[str, Any]]:
        """Give fixes [placed, upto) of the window to the kernel; bucket what it says."""
        c = self._cols
        a = {k: np.asarray(c[k], dtype=float) for k in ("t", "p", "x", "y", "h", "rpm")}
        own = np.asarray(c["own"], dtype=np.int64)
        applied = np.asarray(c["applied"], dtype=float)
        v = np.asarray(c["v"], dtype=float)
        lo = self._placed
        count = np.zeros(len(own), dtype=bool)
        count[lo:upto] = True
        cols = RecordColumns(
            a["t"], a["p"], a["x"], a["y"], np.nan_to_num(a["h"]), a["rpm"], own,
            applied * self.width * v * 6.0 / 60.0,  # as the report: no shaft speed
            count=count,
        )  # fmt: skip
        res = records_applied(
            self.cells, cols, self.cal, self.job.lag_s, self.job.antenna_forward_m, MAX_GAP_S
        )
        t = a["t"]
        t0, t1 = float(t[lo]), float(t[upto - 1])
        for i in np.flatnonzero(res.m2_g).tolist():
            b = self._bucket(int(i))
            b.mass_g += float(res.m2_g[i])
            b.touch_t = t1
            b.span0, b.span1 = min(b.span0, t0), max(b.span1, t1)
        if res.outside_g > 0:
            b = self._bucket(-1)
            b.mass_g += res.outside_g
            b.touch_t = t1
            b.span0, b.span1 = min(b.span0, t0), max(b.span1, t1)
        down = c["down"]
        for i in range(lo, upto):
            if not down[i]:
                continue
            b = self._bucket(int(own[i]))
            ti = float(t[i])
            b.n_fixes += 1
            b.worked_s += float(res.dts[i])
            b.speed_sum += float(v[i])
            b.target_sum += float(c["target"][i])
            b.applied_sum += float(applied[i])
            b.t_entry, b.t_exit = min(b.t_entry, ti), max(b.t_exit, ti)
            b.touch_t = max(b.touch_t, ti)
            b.flags.update(c["alarms"][i])
        self._own_now = int(own[upto - 1])
        self._placed = upto
        if not final:
            self._trim()
        return self._emit(t1)

    def _trim(self) -> None:
        """Drop fixes no longer needed: keep the last positioned fix before the first unplaced
        one (the landing interpolation's left neighbour) and everything after it. Without
        one, the job's first track point is still ahead and nothing before is needed."""
        c = self._cols
        x = c["x"]
        j = self._placed - 1
        while j >= 0 and not math.isfinite(x[j]):
            j -= 1
        keep = j if j >= 0 else self._placed
        if keep <= 0:
            return
        for k in c:
            del c[k][:keep]
        del self._dts[:keep]
        self._placed -= keep
        self._settled -= keep

    def _bucket(self, i: int) -> _Bucket:
        b = self._buckets.get(i)
        if b is None:
            b = self._buckets[i] = _Bucket()
        return b

    def _emit(self, now: float, everything: bool = False) -> list[dict[str, Any]]:
        """Cell records of the cells left: not the current one, nothing added for HOLD_S."""
        out = []
        for i in sorted(self._buckets):
            b = self._buckets[i]
            if not everything and (i == self._own_now or b.touch_t > now - HOLD_S):
                continue
            del self._buckets[i]
            if b.n_fixes == 0 and b.mass_g <= 0:
                continue
            n = b.n_fixes
            t0, t1 = (b.t_entry, b.t_exit) if n else (b.span0, b.span1)
            out.append(
                {
                    "job_id": self.job.job_id,
                    "cell_seq": int(self.job.seq[i]) if i >= 0 else None,
                    "t_entry": t0,
                    "t_exit": t1,
                    "n_fixes": n,
                    "worked_s": b.worked_s,
                    "mass_g": b.mass_g,
                    "driven_m": float(self.driven[i]) if i >= 0 else None,
                    "mean_speed_m_s": b.speed_sum / n if n else None,
                    "mean_target_rate_kg_ha": b.target_sum / n if n else None,
                    "mean_applied_rate_kg_ha": b.applied_sum / n if n else None,
                    "flags": sorted(b.flags),
                }
            )
        return out


_COLS = ("t", "p", "x", "y", "h", "rpm", "own", "applied", "target", "v", "down", "alarms")


def _num(v: Any) -> float:
    return float("nan") if v is None else float(v)


class RawLog:
    """The job's full 10 Hz log on the tractor: one JSON record per line, appended.

    Flushed to the operating system after every write (a killed agent keeps every
    record it queued), fsynced on ``close``."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fh = self.path.open("a", encoding="utf-8")

    def read(self) -> list[dict[str, Any]]:
        """Every complete record (a line cut short by a kill is left out)."""
        out = []
        with self.path.open(encoding="utf-8") as fh:
            for line in fh:
                if line.endswith("\n"):
                    out.append(json.loads(line))
        return out

    def write(self, records: list[dict[str, Any]]) -> None:
        self._fh.write(
            "".join(json.dumps(r, separators=(",", ":"), allow_nan=False) + "\n" for r in records)
        )
        self._fh.flush()

    def close(self) -> None:
        if not self._fh.closed:
            self._fh.flush()
            os.fsync(self._fh.fileno())
            self._fh.close()


def raw_log_path(state_dir: str | Path, job_id: int) -> Path:
    return Path(state_dir) / "rawlog" / f"job-{int(job_id)}.jsonl"


def pack_raw_log(path: str | Path) -> bytes:
    """The job's log as one gzip file (what ``upload-log`` sends)."""
    return gzip.compress(Path(path).read_bytes(), compresslevel=6)


class ThinUplink:
    """The agent's queue for a thin-profile job: takes every fix, sends the thin profile.

    Duck-types the ``TelemetryQueue`` calls the agent and the simulator make
    (``put``, ``put_many``, ``backlog``, ``machine_id``); ``track`` and ``cells`` are
    the two real queues, each sent by the uplink senders on its own stream.
    """

    def __init__(
        self,
        job: JobPackage,
        track: TelemetryQueue,
        cells: TelemetryQueue,
        raw_log_file: str | Path,
        track_period_s: float = TRACK_PERIOD_S,
    ) -> None:
        self.job = job
        self.track = track
        self.cells = cells
        self.machine_id = track.machine_id
        self.track_period_s = track_period_s
        self.acc = CellAccumulator(job)
        self._key = f"thin_cells_emitted:{job.job_id}"
        self._emitted = int(cells.info(self._key) or 0)
        self._last_track_t: float | None = None
        self.fixes = 0
        path = Path(raw_log_file)
        if path.exists():  # a restarted agent: rebuild the accumulator from its own log
            self._replay(RawLog(path).read())
        self.raw = RawLog(path)

    def _replay(self, records: list[dict[str, Any]]) -> None:
        made: list[dict[str, Any]] = []
        for rec in records:
            made.extend(self.acc.add(rec))
            self._last_track_t = self._track_due(rec, self._last_track_t)[1]
        self.fixes = len(records)
        rest = made[self._emitted :]  # made before the kill, but not yet queued
        if rest:
            self._queue_cells(rest)
        log.info("thin uplink: replayed %d fixes of job %s", len(records), self.job.job_id)

    def _track_due(self, rec: dict[str, Any], last: float | None) -> tuple[bool, float | None]:
        t = float(rec["t"])
        if last is None or t - last >= self.track_period_s - 1e-6 or t < last:
            return True, t
        return False, last

    def put(self, record: dict[str, Any]) -> int:
        seqs = self.put_many([record])
        return seqs[-1] if seqs else 0

    def put_many(self, records: list[dict[str, Any]]) -> list[int]:
        """Every fix goes to the raw log and the accumulator; one per second to the track."""
        clean = []
        for rec in records:
            rec["machine_id"] = self.machine_id
            reasons = sanitize_record(rec)
            if reasons and reasons[0].startswith("drop:"):
                log.warning("fix not logged: %s", reasons[0])
                continue
            clean.append(rec)
        self.raw.write(clean)
        track = []
        made: list[dict[str, Any]] = []
        for rec in clean:
            made.extend(self.acc.add(rec))
            due, last = self._track_due(rec, self._last_track_t)
            if due:
                tr = dict(rec)
                prev = self._last_track_t
                if prev is not None and last is not None and last > prev:
                    tr["fix_period_s"] = min(last - prev, MAX_FIX_PERIOD_S)
                tr["cell_seq"] = None  # cells are counted by the cell records
                track.append(tr)
            self._last_track_t = last
        self.fixes += len(clean)
        seqs = self.track.put_many(track) if track else []
        if made:
            self._queue_cells(made)
        return seqs

    def _queue_cells(self, made: list[dict[str, Any]]) -> None:
        self._emitted += len(made)
        self.cells.put_many(made, info={self._key: str(self._emitted)})

    def flush(self) -> int:
        """End of the job (or of this run): the cells not yet sent. Returns records queued."""
        made = self.acc.flush()
        if made:
            self._queue_cells(made)
        self.raw.close()
        return len(made)

    def backlog(self) -> int:
        return self.track.backlog() + self.cells.backlog()

    def stats(self) -> dict[str, Any]:
        return {
            "profile": "thin",
            "fixes": self.fixes,
            "track": self.track.stats(),
            "cells": self.cells.stats(),
            "raw_log": str(self.raw.path),
        }
