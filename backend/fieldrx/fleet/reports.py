"""As-applied report of a job: per-cell mass, accuracy (seed 001 eq. 17-18), coverage, totals.

Per cell (path order, planned rate M in kg/ha):

* theoretical mass M1 = M v t l / 36 g (seed 001 eq. 17; SCIENCE.md erratum:
  grams) with v t the distance driven in the cell and l the implement width:
  M1 = M * l * d / 10 g, d = the cell's centre line (between the midpoints of
  its two cut edges) inside the field, as the edge simulator counts it; for a
  whole cell this is M * area / 10;
* applied mass M2: what landed in the cell. Each record's fix period dt (the
  ``fix_period_s`` it carries; records without one: to the next record, 0
  across a gap longer than ``max_gap_s``; ``fieldrx_edge.asapplied.fix_periods``)
  meters flow(actual shaft speed) * dt grams (the machine's calibration, trapezoid
  between this record and the next); that mass lands T_lag later (seed 001
  eq. 16) at the outlet, i.e. where the track is at t + dt/2 + T_lag, moved
  ``antenna_forward_m`` along the heading. The landing point is located in the
  cells' quadrilaterals, or in the real cell polygon (``plan_cells.geom``) for
  the cells whose polygon differs from the rectangle (field edge, holes,
  headland rings: ``formats.jobpackage.shaped_cells``, the cells that carry
  their shape in the job package); where cells overlap, the record's own cell
  wins; mass landing off the field or outside every cell is "outside". Records
  without positions fall back to their own ``cell_seq`` (the lag-compensated cell
  the agent metered for);
* for those shaped cells d is the length inside the real polygon of the centre
  lines of the cell and its same-swath neighbours, joined (5 m straight on at a
  swath's end), as the edge simulator's ``shape_drive_len`` counts it;
* accuracy theta = (1 - |M1 - M2| / M1) * 100 % (seed 001 eq. 18).

Coverage = cells that received fertilizer / cells with a planned rate > 0.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
from fieldrx_edge.asapplied import fix_periods, metered_mass_g
from fieldrx_edge.metering import calibration_from_dict
from geoalchemy2.shape import to_shape
from sqlalchemy import text
from sqlalchemy.orm import Session

from fieldrx.db.models import Field, Job, Machine, Plan, Prescription
from fieldrx.formats.jobpackage import shaped_cells
from fieldrx.geo.crs import to_utm

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
    # prescribed cells (rate > 0) where nothing landed, path order (the job-end alert's list)
    not_applied_seqs: list[int] = field(default_factory=list)
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


def shaped_driven_length(
    corners: np.ndarray, swath: np.ndarray, polys: np.ndarray, which: np.ndarray
) -> np.ndarray:
    """Driving-line length inside the real polygon of each cell in ``which``.

    The line joins the centre lines (rear -> front cut-edge midpoints; corners are
    rear-right, front-right, front-left, rear-left) of the cell and of its neighbours
    in the same swath, 5 m straight on where the swath starts or ends: the same line
    the edge simulator measures (``fieldrx_edge.sim.simulator.shape_drive_len``).
    """
    c = corners.reshape(-1, 4, 2)
    n = len(c)
    rear = (c[:, 3] + c[:, 0]) / 2
    front = (c[:, 1] + c[:, 2]) / 2
    out = np.zeros(n)
    lines = []
    for i in which:
        d = front[i] - rear[i]
        u = d / max(float(np.hypot(*d)), 1e-9)
        pts = (
            [rear[i - 1], front[i - 1]] if i > 0 and swath[i - 1] == swath[i] else [rear[i] - 5 * u]
        )
        pts += [rear[i], front[i]]
        if i + 1 < n and swath[i + 1] == swath[i]:
            pts += [rear[i + 1], front[i + 1]]
        else:
            pts.append(front[i] + 5 * u)
        lines.append(shapely.linestrings(np.asarray(pts)))
    if len(lines):
        out[which] = shapely.length(shapely.intersection(np.asarray(lines), polys[which]))
    return out


def _metered_g(
    machine: Machine | None,
    rpm: np.ndarray,
    applied: np.ndarray,
    width: float,
    v: np.ndarray,
    dts: np.ndarray,
) -> np.ndarray:
    """Grams metered in each record's fix period (trapezoid over the shaft speed)."""
    flow = np.full(len(rpm), np.nan)
    if machine is not None and machine.calibration:
        cal = calibration_from_dict(machine.calibration)
        ok = np.isfinite(rpm)
        flow[ok] = [max(0.0, cal.flow_g_min(r)) if r > 0 else 0.0 for r in rpm[ok]]
    # records without a shaft speed: the applied rate over the strip driven
    fallback = applied * width * v * 6.0  # kg/ha * m * m/s -> g/min
    flow = np.where(np.isfinite(flow), flow, fallback) / 60.0  # g/s
    return metered_mass_g(flow, dts)


def _landing_cells(
    t: np.ndarray,
    dts: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    heading_deg: np.ndarray,
    cell: np.ndarray,
    seqs: np.ndarray,
    cell_geoms: np.ndarray,
    boundary: Any,
    lag_s: float,
    forward_m: float,
) -> np.ndarray:
    """Index (into seqs) of the cell where each record's metered mass lands; -1 outside."""
    n = len(t)
    out = np.full(n, -1, dtype=np.int64)
    have = np.isfinite(x) & np.isfinite(y)
    if have.sum() >= 2 and len(seqs):
        tl = t + dts / 2 + lag_s
        xl = np.interp(tl, t[have], x[have])
        yl = np.interp(tl, t[have], y[have])
        hl = np.radians(
            np.interp(
                tl,
                t[have],
                np.unwrap(np.radians(heading_deg[have]), period=2 * np.pi) * 180 / np.pi,
            )
        )
        xl = xl + forward_m * np.sin(hl)
        yl = yl + forward_m * np.cos(hl)
        tree = shapely.STRtree(cell_geoms)
        pts = shapely.points(xl, yl)
        pi, ci = tree.query(pts, predicate="intersects")
        if len(pi):
            # where cells overlap (a swath's footprint over the headland ring it overlaps,
            # ``formats.jobpackage.shaped_cells``), the cell the agent metered for wins, as
            # its path-ordered locator prefers the cell being driven; else the lowest index
            pos = np.searchsorted(seqs, cell)
            own = np.where((pos < len(seqs)) & (seqs[np.minimum(pos, len(seqs) - 1)] == cell),
                           pos, -1)  # fmt: skip
            order = np.lexsort((ci, ci != own[pi], pi))
            pi, ci = pi[order], ci[order]
            first, at = np.unique(pi, return_index=True)
            out[first] = ci[at]
        if boundary is not None:
            off = ~shapely.contains_xy(boundary, xl, yl)
            out[off] = -1
        # records before the track starts or after it ends land somewhere unknown
        outside_track = (tl < t[have][0]) | (tl > t[have][-1] + 1.0)
        out[outside_track] = -1
    none = ~have
    if none.any():
        pos = np.searchsorted(seqs, cell[none])
        ok = (cell[none] >= 0) & (pos < len(seqs))
        ok[ok] = seqs[pos[ok]] == cell[none][ok]
        out[np.flatnonzero(none)[ok]] = pos[ok]
    return out


def job_plan(session: Session, job: Job) -> Plan:
    if job.plan_id is not None:  # sensor kinds (issue 13) drive a plan directly
        plan = session.get(Plan, job.plan_id)
        assert plan is not None
        return plan
    rx = session.get(Prescription, job.prescription_id)
    assert rx is not None
    plan = session.get(Plan, rx.plan_id)
    assert plan is not None
    return plan


def build_report(session: Session, job: Job, max_gap_s: float = MAX_GAP_S) -> JobReport:
    machine = session.get(Machine, job.machine_id)
    width = machine.width_m if machine is not None else 0.0
    plan = job_plan(session, job)
    fld = session.get(Field, plan.field_id)
    cells = session.execute(
        text(
            "SELECT pc.seq, pc.swath, pc.corners_utm, coalesce(r.rate_kg_ha, 0) AS rate,"
            " ST_AsBinary(ST_Transform(pc.geom, :epsg)) AS geom"
            " FROM plan_cells pc"
            " LEFT JOIN prescription_versions v ON v.prescription_id = :rx AND v.version = :ver"
            " LEFT JOIN prescription_rates r ON r.version_id = v.id AND r.seq = pc.seq"
            " WHERE pc.plan_id = :plan ORDER BY pc.seq"
        ),
        {
            "rx": job.prescription_id,
            "ver": job.prescription_version,
            "plan": plan.id,
            "epsg": fld.utm_epsg if fld is not None else 4326,
        },
    ).all()
    n = len(cells)
    seqs = np.asarray([c.seq for c in cells], dtype=np.int64)
    swath = np.asarray([c.swath for c in cells], dtype=np.int64)
    rate = np.asarray([c.rate for c in cells], dtype=float)
    corners = np.asarray([c.corners_utm for c in cells], dtype=float).reshape(n, 8)
    area = quad_area(corners) if n else np.zeros(0)
    boundary = to_utm(to_shape(fld.boundary), fld.utm_epsg) if fld is not None else None
    swath_w = float((plan.params or {}).get("swath_width_m") or width or 1.0)
    drive = driven_length(corners, swath_w, boundary)
    # real cells where they differ from the rectangle (edge, holes, headland rings)
    quads = shapely.polygons(corners.reshape(-1, 4, 2)) if n else np.zeros(0, dtype=object)
    polys = shapely.from_wkb(np.asarray([bytes(c.geom) for c in cells], dtype=object))
    shaped = shaped_cells(polys, corners) if n else np.zeros(0, dtype=bool)
    which = np.flatnonzero(shaped)
    cell_geoms = np.where(shaped, polys, quads) if n else quads
    if len(which):
        drive[which] = shaped_driven_length(corners, swath, polys, which)[which]
    m1 = rate * width * drive / 10.0  # seed 001 eq. 17: M v t l / 36 g, v t = driven length

    recs = session.execute(
        text(
            "SELECT extract(epoch FROM t)::float8, cell_seq, applied_rate_kg_ha,"
            " target_rate_kg_ha, coalesce(speed_filtered_m_s, speed_raw_m_s), implement_down,"
            " actual_shaft_rpm, heading_deg,"
            " ST_X(ST_Transform(geom, :epsg)), ST_Y(ST_Transform(geom, :epsg)), fix_period_s"
            " FROM telemetry WHERE machine_id = :m AND job_id = :j ORDER BY t, stream, seq"
        ),
        {"m": job.machine_id, "j": job.id, "epsg": fld.utm_epsg if fld is not None else 4326},
    ).all()
    nr = len(recs)
    if nr:
        col = list(zip(*recs, strict=True))

        def arr(i: int, default: float = np.nan) -> np.ndarray:
            return np.asarray([default if v is None else v for v in col[i]], dtype=float)

        t = arr(0)
        cell = np.asarray([-1 if v is None else v for v in col[1]], dtype=np.int64)
        applied, target, v, rpm = arr(2, 0.0), arr(3), arr(4, 0.0), arr(6)
        down = np.asarray(col[5], dtype=bool)
        heading, x, y = arr(7, 0.0), arr(8), arr(9)
        dts = fix_periods(t, arr(10), max_gap_s)
        mass = _metered_g(machine, rpm, applied, width, v, dts)
        time_worked = float(dts[down].sum())
        idx = _landing_cells(
            t, dts, x, y, heading, cell, seqs, cell_geoms, boundary,
            machine.lag_s if machine else 0.0, machine.antenna_forward_m if machine else 0.0,
        )  # fmt: skip
        in_cell = idx >= 0
        m2 = np.bincount(idx[in_cell], weights=mass[in_cell], minlength=n)
        outside_g = float(mass[~in_cell].sum())
        # per-cell record statistics use the cell the agent metered for
        pos = np.searchsorted(seqs, cell)
        sel = (cell >= 0) & (pos < n) & down
        sel[sel] = seqs[pos[sel]] == cell[sel]
        cnt = np.bincount(pos[sel], minlength=n)
        asum = np.bincount(pos[sel], weights=applied[sel], minlength=n)
        tsum = np.bincount(pos[sel], weights=np.nan_to_num(target[sel]), minlength=n)
        first = np.full(n, np.inf)
        last = np.full(n, -np.inf)
        np.minimum.at(first, pos[sel], t[sel])
        np.maximum.at(last, pos[sel], t[sel])
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
    planned = m1 > 0  # cells the machine drove over with a target (M1 of eq. 17)
    done = m2 > 0
    applied_acc = acc[planned & done]
    prescribed = rate > 0  # cells the prescription asks fertilizer for
    return JobReport(
        job_id=job.id,
        name=job.name,
        state=job.state,
        machine_id=job.machine_id,
        implement_width_m=width,
        plan_id=plan.id,
        n_cells=n,
        cells_planned=int(prescribed.sum()),
        cells_applied=int((prescribed & done).sum()),
        coverage_pct=float(100.0 * (prescribed & done).sum() / prescribed.sum())
        if prescribed.any()
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
        not_applied_seqs=[int(v) for v in seqs[prescribed & ~done]],
        cells=out_cells,
    )
