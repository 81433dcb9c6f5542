"""As-applied report of a job: per-cell mass, accuracy (seed 001 eq. 17-18), coverage, totals.

Per cell (path order, planned rate M in kg/ha) the figures come from the one
as-applied kernel, ``fieldrx_edge.asapplied`` (seed 001 eq. 16-18; the edge
simulator uses the same functions, so the two agree to rounding):

* theoretical mass M1 = M * l * d / 10 g (eq. 17, docs/science.md erratum: grams),
  l the implement width, d the cell's driving line inside the cell's polygon and
  the field (``asapplied.driven_length``);
* applied mass M2: each record's fix period meters flow(actual shaft speed)
  * dt grams (the machine's calibration, ``asapplied.records_applied``), landing
  T_lag later (eq. 16) along the track, ``antenna_forward_m`` ahead, split among
  the cells' polygons (the 4-corner rectangle, or the real polygon from the
  cell store, ``fieldrx.store.load_cells``, for the cells whose polygon differs from it:
  ``formats.jobpackage.shaped_cells``, the cells that carry their shape in the
  job package); where cells overlap, the record's own cell wins; mass landing in
  no cell or off the field (outside its ring, in a hole) is "outside";
* accuracy theta = (1 - |M1 - M2| / M1) * 100 % (eq. 18).

Coverage = cells that received fertilizer / cells with a planned rate > 0.

Amounts and areas have one definition each, shared with the prescription screen and
every export (``agronomy.prescription.planned_kg``; areas in the field's UTM plane,
``geo.crs.AREA_BASIS``): a cell's area is its real polygon inside the field (the cell
store's ``area_m2``, never the nominal rectangle, so the cells never add up to more than
the field); planned = sum(rate * area) over the version's cells; never applied = the
planned amount of prescribed cells where nothing landed. M1 (eq. 17) stays the accuracy
reference of each cell: the mass the driven line asked for, not the version's plan.

A job run with uplink profile ``thin`` has no 10 Hz records here:
its tractor ran the same kernel over its own log and sent one record per cell
(``fleet.cellrecords``, ``fieldrx_edge.uplink.thin``). Its report sums those
per cell (M2, fixes, worked time, mean rates, first/last fix) instead of
integrating records, and takes M1 and everything else as above; its 1 Hz
track only gives the job's first and last time. A job that has cell records
is reported from them (an agent keeps a job's profile from its start).
"""

from __future__ import annotations

import datetime as dt
import gzip
import hashlib
import json
import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np
from fieldrx_edge.asapplied import (
    Cells,
    RecordColumns,
    driven_length,
    m1_g,
    records_applied,
    theta_pct,
)
from fieldrx_edge.metering import calibration_from_dict
from geoalchemy2.shape import to_shape
from sqlalchemy import select, text
from sqlalchemy.orm import Session

from fieldrx.agronomy.prescription import application_outcome, planned_kg
from fieldrx.db.models import Field, Job, Machine, Plan, Prescription, PrescriptionVersion
from fieldrx.fleet.cellrecords import job_cell_totals
from fieldrx.fleet.operator_events import operator_events
from fieldrx.fleet.partitions import job_window
from fieldrx.formats.jobpackage import shaped_cells
from fieldrx.geo.crs import AREA_BASIS, to_utm
from fieldrx.store import load_cells, load_rates

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
    uplink: str = "full"  # the profile the job's figures came from: full | thin (cell records)
    field_area_m2: float = 0.0  # the field's stored area (same basis as the cells')
    planned_area_m2: float = 0.0  # area of the prescribed cells (rate > 0)
    applied_area_m2: float = 0.0  # area of the cells where product landed
    never_applied_kg: float = 0.0  # planned amount of the prescribed cells nothing reached
    area_basis: str = AREA_BASIS
    # target vs applied over the prescribed cells (agronomy.prescription.application_outcome)
    outcome: dict[str, float | None] = field(default_factory=dict)
    cells: list[CellReport] = field(default_factory=list)
    # the operator's overrides and alarm acknowledgements (fleet.operator_events)
    operator: dict[str, Any] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        out = {k: v for k, v in self.__dict__.items() if k != "cells"}
        out["first_t"] = _iso(self.first_t)
        out["last_t"] = _iso(self.last_t)
        return out


def _iso(t: float | None) -> str | None:
    return None if t is None else dt.datetime.fromtimestamp(t, dt.UTC).isoformat()


def _rings(poly: Any) -> list[list[float]]:
    """Rings of a (Multi)Polygon as open flat x y lists (the job package's shape encoding)."""
    parts = list(poly.geoms) if poly.geom_type == "MultiPolygon" else [poly]
    rings: list[list[float]] = []
    for p in parts:
        if p.geom_type != "Polygon" or p.is_empty:
            continue
        for ring in (p.exterior, *p.interiors):
            pts = np.asarray(ring.coords, dtype=float)[:-1, :2]
            if len(pts) >= 3:
                rings.append(pts.ravel().tolist())
    return rings


def job_plan(session: Session, job: Job) -> Plan:
    if job.plan_id is not None:  # sensor kinds drive a plan directly
        plan = session.get(Plan, job.plan_id)
        assert plan is not None
        return plan
    rx = session.get(Prescription, job.prescription_id)
    assert rx is not None
    plan = session.get(Plan, rx.plan_id)
    assert plan is not None
    return plan


def _version_id(session: Session, job: Job) -> int | None:
    """Id of the prescription version the job applies (None: a sensor kind, no rates)."""
    if job.prescription_id is None:
        return None
    return session.scalar(
        select(PrescriptionVersion.id).where(
            PrescriptionVersion.prescription_id == job.prescription_id,
            PrescriptionVersion.version == job.prescription_version,
        )
    )


# the job's records in report order, one float column each; NULL -> the default the report
# uses (NaN: unknown; 0: no rate, no speed, no heading; -1: no cell)
_RECORDS_SQL = (
    "SELECT extract(epoch FROM t)::float8, coalesce(cell_seq, -1)::float8,"
    " coalesce(applied_rate_kg_ha, 0), coalesce(target_rate_kg_ha, 'NaN'),"
    " coalesce(speed_filtered_m_s, speed_raw_m_s, 0), implement_down::int::float8,"
    " coalesce(actual_shaft_rpm, 'NaN'), coalesce(heading_deg, 0),"
    " coalesce(ST_X(ST_Transform(geom, %(epsg)s)), 'NaN'),"
    " coalesce(ST_Y(ST_Transform(geom, %(epsg)s)), 'NaN'), coalesce(fix_period_s, 'NaN')"
    " FROM telemetry WHERE machine_id = %(m)s AND job_id = %(j)s AND t BETWEEN %(t0)s AND %(t1)s"
    " ORDER BY t, stream, seq"
)


def _job_records(session: Session, job: Job, epsg: int) -> np.ndarray:
    """(n, 11) float matrix of the job's records (``_RECORDS_SQL`` columns), read inside
    the job's time span (``fleet.partitions.job_window``: only the job's days)."""
    params = {"m": job.machine_id, "j": job.id, "epsg": epsg}
    params.update(job_window(session, job.machine_id, job.id))
    raw = session.connection().connection.dbapi_connection
    assert raw is not None
    with raw.cursor(binary=True) as cur:  # type: ignore[attr-defined]
        cur.execute(_RECORDS_SQL, params)
        rows = cur.fetchall()
    return np.asarray(rows, dtype=float).reshape(len(rows), 11)


ProgressFn = Callable[[float, str], None]


def build_report(
    session: Session,
    job: Job,
    max_gap_s: float = MAX_GAP_S,
    progress: ProgressFn | None = None,
) -> JobReport:
    """The job's report; ``progress(share, message)`` is told the stage (a report task
    shows it; it may raise ``Cancelled`` to stop)."""
    step: ProgressFn = progress or (lambda share, message: None)
    step(0.05, "loading the plan's cells")
    machine = session.get(Machine, job.machine_id)
    width = machine.width_m if machine is not None else 0.0
    plan = job_plan(session, job)
    fld = session.get(Field, plan.field_id)
    epsg = fld.utm_epsg if fld is not None else 0
    cells = load_cells(session, plan.id, epsg)
    n = len(cells)
    seqs, swath, polys = cells.seq, cells.swath, cells.polygons_utm
    corners = cells.corners_utm.reshape(n, 8)
    rate = np.zeros(n)  # planned rate per cell; 0 where the version has none (sensor kinds)
    ver = _version_id(session, job)
    if ver is not None:
        rseq, rrate, _, _ = load_rates(session, ver)
        pos = np.searchsorted(seqs, rseq)
        hit = pos < n
        hit[hit] = seqs[pos[hit]] == rseq[hit]
        rate[pos[hit]] = rrate[hit]
    # real cells where they differ from the rectangle (edge, holes, headland rings)
    shaped = shaped_cells(polys, corners) if n else np.zeros(0, dtype=bool)
    boundary = to_utm(to_shape(fld.boundary), fld.utm_epsg) if fld is not None else None
    geo = Cells.build(
        corners,
        swath,
        {int(i): _rings(polys[i]) for i in np.flatnonzero(shaped)},
        _rings(boundary) if boundary is not None else None,
    )
    area = cells.area_m2  # the real cell inside the field (one definition, see module doc)
    m1 = m1_g(rate, width, driven_length(geo))

    step(0.2, "reading the job's records")
    thin = job_cell_totals(session, job.id, job.machine_id)
    # one float matrix, straight from the driver: building a Row per record and reading
    # it column by column cost ~40 us per record (0.85 s of a 21k-record report)
    rec = (
        np.empty((0, 11))
        if thin
        else _job_records(session, job, fld.utm_epsg if fld is not None else 4326)
    )
    nr = len(rec)
    step(0.6, f"metering {nr:,} records into {n:,} cells")
    if thin:
        m2, cnt, asum, tsum, first, last, outside_g, time_worked = _thin_cells(thin, seqs)
        nr, first_t, last_t = _thin_span(session, job, thin, first, last)
    elif nr:
        t, cell_f, applied, target, v, down_f, rpm, heading, x, y, period = np.ascontiguousarray(
            rec.T
        )
        cell = cell_f.astype(np.int64)
        down = down_f > 0.5
        # each record's own cell as an index into the path-ordered cells (-1: none)
        pos = np.searchsorted(seqs, cell)
        ok = (cell >= 0) & (pos < n)
        ok[ok] = seqs[pos[ok]] == cell[ok]
        own = np.where(ok, pos, -1)
        cal = (
            calibration_from_dict(machine.calibration) if machine and machine.calibration else None
        )
        cols = RecordColumns(
            t, period, x, y, heading, rpm, own,
            applied * width * v * 6.0 / 60.0,  # no shaft speed: the applied rate over the strip
        )  # fmt: skip
        applied_ka = records_applied(
            geo, cols, cal,
            machine.lag_s if machine else 0.0, machine.antenna_forward_m if machine else 0.0,
            max_gap_s,
        )  # fmt: skip
        m2 = applied_ka.m2_g
        outside_g = applied_ka.outside_g
        time_worked = float(applied_ka.dts[down].sum())
        # per-cell record statistics use the cell the agent metered for
        sel = (own >= 0) & down
        cnt = np.bincount(own[sel], minlength=n)
        asum = np.bincount(own[sel], weights=applied[sel], minlength=n)
        tsum = np.bincount(own[sel], weights=np.nan_to_num(target[sel]), minlength=n)
        first = np.full(n, np.inf)
        last = np.full(n, -np.inf)
        np.minimum.at(first, own[sel], t[sel])
        np.maximum.at(last, own[sel], t[sel])
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
    step(0.9, "accuracy and totals")
    acc = theta_pct(m1, m2)  # seed 001 eq. 18
    with np.errstate(divide="ignore", invalid="ignore"):
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
        planned_total_kg=planned_kg(rate[prescribed], area[prescribed]),
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
        uplink="thin" if thin else "full",
        field_area_m2=float(fld.area_m2) if fld is not None else 0.0,
        planned_area_m2=float(area[prescribed].sum()),
        applied_area_m2=float(area[done].sum()),
        never_applied_kg=planned_kg(rate[prescribed & ~done], area[prescribed & ~done]),
        outcome=application_outcome(rate[prescribed], applied_rate[prescribed], area[prescribed]),
        cells=out_cells,
        operator=operator_events(session, job.machine_id, job.id),
    )


def _thin_cells(thin: list[Any], seqs: np.ndarray) -> tuple[Any, ...]:
    """Per-cell arrays (path order) from a thin job's cell records summed per cell
    (``cellrecords.job_cell_totals``): M2, fixes, applied/target rate sums, first/last fix,
    mass in no cell, time worked."""
    n = len(seqs)
    m2, asum, tsum = np.zeros(n), np.zeros(n), np.zeros(n)
    cnt = np.zeros(n, dtype=np.int64)
    first, last = np.full(n, np.inf), np.full(n, -np.inf)
    outside_g = time_worked = 0.0
    for cell, fixes, worked, mass, t_sum, a_sum, t0, t1 in thin:
        time_worked += float(worked or 0.0)
        i = int(np.searchsorted(seqs, cell)) if cell is not None else n
        if i >= n or seqs[i] != cell:  # no cell, or one this plan does not have
            outside_g += float(mass or 0.0)
            continue
        m2[i] += float(mass or 0.0)
        cnt[i] += int(fixes or 0)
        tsum[i] += float(t_sum or 0.0)
        asum[i] += float(a_sum or 0.0)
        if t0 is not None:
            first[i] = min(first[i], t0)
            last[i] = max(last[i], t1)
    return m2, cnt, asum, tsum, first, last, outside_g, time_worked


def _thin_span(
    session: Session, job: Job, thin: list[Any], first: np.ndarray, last: np.ndarray
) -> tuple[int, float | None, float | None]:
    """Records behind a thin job's report (track + cell records) and its first/last time."""
    n, t0, t1 = session.execute(
        text(
            "SELECT (SELECT count(*) FROM telemetry WHERE machine_id = :m AND job_id = :j)"
            " + (SELECT count(*) FROM job_cell_records WHERE machine_id = :m AND job_id = :j),"
            " least((SELECT extract(epoch FROM min(t))::float8 FROM telemetry"
            "        WHERE machine_id = :m AND job_id = :j),"
            "       (SELECT extract(epoch FROM min(t_entry))::float8 FROM job_cell_records"
            "        WHERE machine_id = :m AND job_id = :j)),"
            " greatest((SELECT extract(epoch FROM max(t))::float8 FROM telemetry"
            "           WHERE machine_id = :m AND job_id = :j),"
            "          (SELECT extract(epoch FROM max(t_exit))::float8 FROM job_cell_records"
            "           WHERE machine_id = :m AND job_id = :j))"
        ),
        {"m": job.machine_id, "j": job.id},
    ).one()
    return int(n), t0, t1


CACHE_JOBS = 16
_cache: OrderedDict[tuple[str, int], tuple[tuple[Any, ...], JobReport]] = OrderedDict()
_cache_lock = threading.Lock()


def report_key(session: Session, job: Job) -> tuple[Any, ...]:
    """What a job's report depends on that can change: its telemetry and cell records (only
    ever added), its state and prescription version, the machine's settings."""
    window = job_window(session, job.machine_id, job.id)
    n, t_max, n_cells, cells_at = session.execute(
        text(
            "SELECT count(*), max(t),"
            " (SELECT count(*) FROM job_cell_records WHERE job_id = :j AND machine_id = :m),"
            " (SELECT max(received_at) FROM job_cell_records WHERE job_id = :j AND machine_id = :m)"
            " FROM telemetry WHERE job_id = :j AND machine_id = :m AND t BETWEEN :t0 AND :t1"
        ),
        {"j": job.id, "m": job.machine_id, **window},
    ).one()
    m = session.get(Machine, job.machine_id)
    machine = (
        None
        if m is None
        else (m.width_m, m.lag_s, m.antenna_forward_m, json.dumps(m.calibration, sort_keys=True))
    )
    return (
        n, t_max, n_cells, cells_at, job.state, job.name, job.updated_at, job.prescription_id,
        job.prescription_version, machine,
    )  # fmt: skip


def report_digest(key: tuple[Any, ...]) -> str:
    """A stable name of a ``report_key`` (stored with a report snapshot: another process
    computes the same digest from the same database state)."""
    return hashlib.sha256(repr(key).encode()).hexdigest()[:32]


def key_records(key: tuple[Any, ...]) -> int:
    """Records a report with this key integrates (telemetry + cell records): its cost."""
    return int(key[0] or 0) + int(key[2] or 0)


def cache_get(session: Session, job: Job, key: tuple[Any, ...]) -> JobReport | None:
    ck = (str(session.get_bind().engine.url), job.id)
    with _cache_lock:
        hit = _cache.get(ck)
        if hit is not None and hit[0] == key:
            _cache.move_to_end(ck)
            return hit[1]
    return None


def clear_cache() -> None:
    """Forget every cached report (tests: a process that has not computed them)."""
    with _cache_lock:
        _cache.clear()


def cache_put(session: Session, job: Job, key: tuple[Any, ...], rep: JobReport) -> None:
    ck = (str(session.get_bind().engine.url), job.id)
    with _cache_lock:
        _cache[ck] = (key, rep)
        _cache.move_to_end(ck)
        while len(_cache) > CACHE_JOBS:
            _cache.popitem(last=False)


StoredFn = Callable[[str], "JobReport | None"]


def cached_report(session: Session, job: Job, stored: StoredFn | None = None) -> JobReport:
    """``build_report``, kept per job until ``report_key`` changes.

    The job map asks for many tiles of one job at once and again on every refresh
    while the job runs; each tile shows the report's per-cell figures (one kernel,
    one definition), computed once per change of the job's telemetry. ``stored(digest)``
    may answer a snapshot another process computed (a report task's) before building.
    """
    key = report_key(session, job)
    rep = cache_get(session, job, key)
    if rep is None and stored is not None:
        rep = stored(report_digest(key))
    if rep is None:
        rep = build_report(session, job)
    cache_put(session, job, key, rep)
    return rep


_CELL_FIELDS = [f.name for f in fields(CellReport)]


def dump_report(rep: JobReport) -> bytes:
    """The report as gzip JSON, cells as columns (a report task's snapshot)."""
    head = {k: v for k, v in asdict(rep).items() if k != "cells"}
    cols = {k: [getattr(c, k) for c in rep.cells] for k in _CELL_FIELDS}
    return gzip.compress(json.dumps({"report": head, "cells": cols}).encode(), compresslevel=3)


def load_report(data: bytes) -> JobReport:
    """``dump_report``'s inverse."""
    obj = json.loads(gzip.decompress(data))
    cols = obj["cells"]
    n = len(cols[_CELL_FIELDS[0]]) if _CELL_FIELDS else 0
    cells = [CellReport(**{k: cols[k][i] for k in _CELL_FIELDS}) for i in range(n)]
    return JobReport(**obj["report"], cells=cells)
