"""As-applied report of a job: per-cell mass, accuracy (seed 001 eq. 17-18), coverage, totals.

Per cell (path order, planned rate M in kg/ha):

* theoretical mass M1 = M v t l / 36 g (seed 001 eq. 17; SCIENCE.md erratum:
  grams) with v t the distance driven in the cell and l the implement width:
  M1 = M * l * d / 10 g, d = the cell's centre line (between the midpoints of
  its two cut edges) inside the field, as the edge simulator counts it; for a
  whole cell this is M * area / 10;
* applied mass M2 = sum over the job's records in that cell (implement down) of
  applied_rate * width * v * dt / 10 g: the mass metered during the record's
  fix period dt (time to the next record, capped at ``max_gap_s`` so a pause
  or lost link adds nothing). The record's ``cell_seq`` is the lag-compensated
  cell the agent was metering for, i.e. where that mass lands;
* accuracy theta = (1 - |M1 - M2| / M1) * 100 % (seed 001 eq. 18).

Coverage = cells that received fertilizer / cells with a planned rate > 0.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
from sqlalchemy import text
from sqlalchemy.orm import Session

from fieldrx.db.models import Job, Machine, Plan, Prescription

MAX_GAP_S = 2.0


@dataclass
class CellReport:
    seq: int
    swath: int
    area_m2: float
    target_rate_kg_ha: float  # planned (prescription version)
    n_records: int
    mean_target_rate_kg_ha: float | None  # what the agent asked for (records)
    mean_applied_rate_kg_ha: float | None  # mean of the records' applied rate
    applied_rate_kg_ha: float  # M2 over the area
    m1_g: float
    m2_g: float
    accuracy_pct: float | None
    first_t: float | None
    last_t: float | None


@dataclass
class JobReport:
    job_id: int
    name: str
    state: str
    machine_id: int
    implement_width_m: float
    plan_id: int
    n_cells: int
    cells_planned: int
    cells_applied: int
    coverage_pct: float
    planned_total_kg: float
    applied_total_kg: float
    applied_in_cells_kg: float
    applied_outside_cells_kg: float
    mean_accuracy_pct: float | None
    min_accuracy_pct: float | None
    time_worked_s: float
    n_records: int
    first_t: float | None
    last_t: float | None
    cells: list[CellReport] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        out = {k: v for k, v in self.__dict__.items() if k != "cells"}
        out["first_t"] = _iso(self.first_t)
        out["last_t"] = _iso(self.last_t)
        return out


def _iso(t: float | None) -> str | None:
    return None if t is None else dt.datetime.fromtimestamp(t, dt.UTC).isoformat()


def quad_area(corners: np.ndarray) -> np.ndarray:
    """Shoelace area of n quadrilaterals given as (n, 8) x0 y0 ... x3 y3."""
    c = corners.reshape(-1, 4, 2)
    x, y = c[..., 0], c[..., 1]
    return 0.5 * np.abs(np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1))


def driven_length(corners: np.ndarray, swath_width_m: float, boundary_utm: Any) -> np.ndarray:
    """Length of each cell's centre line inside the field (m).

    The centre line joins the midpoints of the two opposite edges whose length
    is nearest the swath width (the cut edges); corners are (n, 8) in UTM.
    """
    c = corners.reshape(-1, 4, 2)
    if len(c) == 0:
        return np.zeros(0)
    e01 = np.linalg.norm(c[:, 1] - c[:, 0], axis=1)
    e12 = np.linalg.norm(c[:, 2] - c[:, 1], axis=1)
    cut01 = np.abs(e01 - swath_width_m) <= np.abs(e12 - swath_width_m)
    a = np.where(cut01[:, None], (c[:, 0] + c[:, 1]) / 2, (c[:, 1] + c[:, 2]) / 2)
    b = np.where(cut01[:, None], (c[:, 2] + c[:, 3]) / 2, (c[:, 3] + c[:, 0]) / 2)
    lines = shapely.linestrings(np.stack([a, b], axis=1))
    if boundary_utm is None:
        return shapely.length(lines)
    shapely.prepare(boundary_utm)
    inside = shapely.contains_properly(boundary_utm, lines)
    out = shapely.length(lines)
    part = ~inside
    if part.any():
        out[part] = shapely.length(shapely.intersection(lines[part], boundary_utm))
    return out


def job_plan(session: Session, job: Job) -> Plan:
    rx = session.get(Prescription, job.prescription_id)
    assert rx is not None
    plan = session.get(Plan, rx.plan_id)
    assert plan is not None
    return plan


def build_report(session: Session, job: Job, max_gap_s: float = MAX_GAP_S) -> JobReport:
    machine = session.get(Machine, job.machine_id)
    width = machine.width_m if machine is not None else 0.0
    plan = job_plan(session, job)
    cells = session.execute(
        text(
            "SELECT pc.seq, pc.swath, pc.corners_utm, coalesce(r.rate_kg_ha, 0) AS rate"
            " FROM plan_cells pc"
            " LEFT JOIN prescription_versions v ON v.prescription_id = :rx AND v.version = :ver"
            " LEFT JOIN prescription_rates r ON r.version_id = v.id AND r.seq = pc.seq"
            " WHERE pc.plan_id = :plan ORDER BY pc.seq"
        ),
        {"rx": job.prescription_id, "ver": job.prescription_version, "plan": plan.id},
    ).all()
    n = len(cells)
    seqs = np.asarray([c.seq for c in cells], dtype=np.int64)
    swath = np.asarray([c.swath for c in cells], dtype=np.int64)
    rate = np.asarray([c.rate for c in cells], dtype=float)
    area = quad_area(np.asarray([c.corners_utm for c in cells], dtype=float)) if n else np.zeros(0)
    m1 = rate * area / 10.0  # seed 001 eq. 17 (g)

    recs = session.execute(
        text(
            "SELECT extract(epoch FROM t)::float8, cell_seq, applied_rate_kg_ha, target_rate_kg_ha,"
            " coalesce(speed_filtered_m_s, speed_raw_m_s), implement_down"
            " FROM telemetry WHERE machine_id = :m AND job_id = :j ORDER BY t, seq"
        ),
        {"m": job.machine_id, "j": job.id},
    ).all()
    nr = len(recs)
    if nr:
        t = np.fromiter((r[0] for r in recs), float, nr)
        cell = np.fromiter((-1 if r[1] is None else r[1] for r in recs), np.int64, nr)
        applied = np.fromiter((r[2] or 0.0 for r in recs), float, nr)
        target = np.fromiter((np.nan if r[3] is None else r[3] for r in recs), float, nr)
        v = np.fromiter((r[4] or 0.0 for r in recs), float, nr)
        down = np.fromiter((bool(r[5]) for r in recs), bool, nr)
        gaps = np.diff(t)
        period = float(np.median(gaps)) if len(gaps) else 0.0
        dts = np.append(gaps, period)
        dts = np.where(dts > max_gap_s, 0.0, np.maximum(dts, 0.0))
        mass = np.where(down, applied * width * v * dts / 10.0, 0.0)  # g metered per record
        time_worked = float(dts[down].sum())
        pos = np.searchsorted(seqs, cell)
        pos_ok = (cell >= 0) & (pos < n)
        in_cell = pos_ok.copy()
        in_cell[pos_ok] = seqs[pos[pos_ok]] == cell[pos_ok]
        idx = pos[in_cell]
        m2 = np.bincount(idx, weights=mass[in_cell], minlength=n)
        cnt = np.bincount(idx[down[in_cell]], minlength=n)
        sel = in_cell & down
        asum = np.bincount(pos[sel], weights=applied[sel], minlength=n)
        tt = np.nan_to_num(target[sel])
        tsum = np.bincount(pos[sel], weights=tt, minlength=n)
        first = np.full(n, np.inf)
        last = np.full(n, -np.inf)
        np.minimum.at(first, pos[sel], t[sel])
        np.maximum.at(last, pos[sel], t[sel])
        outside_g = float(mass[~in_cell].sum())
        first_t, last_t = float(t[0]), float(t[-1])
    else:
        m2 = np.zeros(n)
        cnt = np.zeros(n, dtype=np.int64)
        asum = tsum = np.zeros(n)
        first = np.full(n, np.inf)
        last = np.full(n, -np.inf)
        outside_g = 0.0
        time_worked = 0.0
        first_t = last_t = None
    with np.errstate(divide="ignore", invalid="ignore"):
        acc = np.where(m1 > 0, (1.0 - np.abs(m1 - m2) / m1) * 100.0, np.nan)  # seed 001 eq. 18
        applied_rate = np.where(area > 0, m2 * 10.0 / area, 0.0)
    out_cells = [
        CellReport(
            seq=int(seqs[i]),
            swath=int(swath[i]),
            area_m2=float(area[i]),
            target_rate_kg_ha=float(rate[i]),
            n_records=int(cnt[i]),
            mean_target_rate_kg_ha=float(tsum[i] / cnt[i]) if cnt[i] else None,
            mean_applied_rate_kg_ha=float(asum[i] / cnt[i]) if cnt[i] else None,
            applied_rate_kg_ha=float(applied_rate[i]),
            m1_g=float(m1[i]),
            m2_g=float(m2[i]),
            accuracy_pct=None if np.isnan(acc[i]) else float(acc[i]),
            first_t=float(first[i]) if np.isfinite(first[i]) else None,
            last_t=float(last[i]) if np.isfinite(last[i]) else None,
        )
        for i in range(n)
    ]
    planned = m1 > 0
    done = m2 > 0
    applied_acc = acc[planned & done]
    return JobReport(
        job_id=job.id,
        name=job.name,
        state=job.state,
        machine_id=job.machine_id,
        implement_width_m=width,
        plan_id=plan.id,
        n_cells=n,
        cells_planned=int(planned.sum()),
        cells_applied=int(done.sum()),
        coverage_pct=float(100.0 * (planned & done).sum() / planned.sum())
        if planned.any()
        else 0.0,
        planned_total_kg=float(m1.sum() / 1000.0),
        applied_total_kg=float((m2.sum() + outside_g) / 1000.0),
        applied_in_cells_kg=float(m2.sum() / 1000.0),
        applied_outside_cells_kg=outside_g / 1000.0,
        mean_accuracy_pct=float(applied_acc.mean()) if len(applied_acc) else None,
        min_accuracy_pct=float(applied_acc.min()) if len(applied_acc) else None,
        time_worked_s=time_worked,
        n_records=nr,
        first_t=first_t,
        last_t=last_t,
        cells=out_cells,
    )
