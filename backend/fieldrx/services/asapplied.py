"""A job's as-applied data as files: the report's per-cell figures and the records' points.

Per-cell figures come from ``fleet.reports.build_report`` (seed 001 eq.
17-18); the points are the job's telemetry records with a position. The
writing is ``formats.asapplied``.
"""

from __future__ import annotations

import csv
import io
from typing import Any

import numpy as np
from geoalchemy2.shape import to_shape
from sqlalchemy import select, text
from sqlalchemy.orm import Session

from fieldrx.db.models import Field, Job, PlanCell, Prescription
from fieldrx.fleet.partitions import job_window
from fieldrx.fleet.reports import JobReport, job_plan
from fieldrx.formats.asapplied import (
    AsAppliedPoints,
    AsAppliedTotals,
    CellRow,
)

POINTS_SQL = text(
    "SELECT extract(epoch FROM t)::float8, ST_X(geom), ST_Y(geom), target_rate_kg_ha,"
    " applied_rate_kg_ha, coalesce(speed_filtered_m_s, speed_raw_m_s), implement_down"
    " FROM telemetry WHERE machine_id = :m AND job_id = :j AND t BETWEEN :t0 AND :t1"
    " AND geom IS NOT NULL ORDER BY t, seq"
)


def job_points(session: Session, job: Job) -> AsAppliedPoints:
    window = job_window(session, job.machine_id, job.id)
    rows = session.execute(POINTS_SQL, {"m": job.machine_id, "j": job.id, **window}).all()

    def col(i: int) -> np.ndarray:
        return np.asarray([np.nan if r[i] is None else r[i] for r in rows], dtype=float)

    return AsAppliedPoints(
        t=col(0),
        lon=col(1),
        lat=col(2),
        target_kg_ha=col(3),
        applied_kg_ha=col(4),
        speed_m_s=col(5),
        down=np.asarray([bool(r[6]) for r in rows], dtype=bool),
    )


def _cells(session: Session, rep: JobReport) -> list[CellRow]:
    geoms = {
        int(s): to_shape(g)
        for s, g in session.execute(
            select(PlanCell.seq, PlanCell.geom).where(PlanCell.plan_id == rep.plan_id)
        ).all()
    }
    return [
        CellRow(
            c.seq,
            c.swath,
            c.n_records,
            c.area_m2,
            c.target_rate_kg_ha,
            c.applied_rate_kg_ha,
            c.m1_g,
            c.m2_g,
            c.accuracy_pct,
            geoms.get(c.seq),
        )
        for c in rep.cells
    ]


CSV_COLUMNS = (
    "seq",
    "swath",
    "area_m2",
    "target_rate_kg_ha",
    "applied_rate_kg_ha",
    "mean_applied_rate_kg_ha",
    "m1_g",
    "m2_g",
    "accuracy_pct",
    "n_records",
)


def cells_csv(rep: JobReport) -> bytes:
    """The report's per-cell table as CSV (``CSV_COLUMNS``; empty = unknown)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for c in rep.cells:  # getattr, not asdict: asdict deep-copies every field (~0.5 ms a row)
        row = [getattr(c, k) for k in CSV_COLUMNS]
        w.writerow(["" if v is None else (round(v, 6) if isinstance(v, float) else v) for v in row])
    return buf.getvalue().encode()


class _JobSource:
    """``formats.export.AsAppliedSource`` over the database: each part read when asked."""

    def __init__(self, session: Session, job: Job, rep: JobReport) -> None:
        self.session, self.job, self.rep = session, job, rep

    def cells_csv(self) -> bytes:
        return cells_csv(self.rep)

    def cell_rows(self) -> list[CellRow]:
        return _cells(self.session, self.rep)

    def points(self) -> AsAppliedPoints:
        return job_points(self.session, self.job)

    def taskdata(self) -> tuple[AsAppliedTotals, dict[str, Any]]:
        session, job, rep = self.session, self.job, self.rep
        plan = job_plan(session, job)
        fld = session.get(Field, plan.field_id)
        rx = session.get(Prescription, job.prescription_id)
        totals = AsAppliedTotals(
            applied_total_kg=rep.applied_total_kg,
            area_applied_m2=rep.applied_area_m2,
            time_worked_s=rep.time_worked_s,
            first_t=rep.first_t,
            last_t=rep.last_t,
            field_area_m2=rep.field_area_m2,
        )
        names = {
            "job_name": job.name,
            "field_name": "" if fld is None else fld.name,
            "boundary_wgs84": None if fld is None else to_shape(fld.boundary),
            "product_name": (rx.product if rx is not None else "") or "fertilizer",
        }
        return totals, names


def export_job(session: Session, job: Job, rep: JobReport, fmt: str) -> tuple[bytes, str, str]:
    """(bytes, media type, file name) of a job's as-applied data in an export format that
    has the ``job`` subject (``formats.export``: the per-cell CSV table, the cell polygons
    and record points as a zipped Shapefile, a TASKDATA.zip with a TimeLog)."""
    from fieldrx.formats.export import JOB, export_format

    kind = export_format(fmt, JOB)
    stem = f"job{job.id}_as_applied"
    data = kind.write_job(_JobSource(session, job, rep), stem)
    return data, kind.media_type, kind.job_filename(stem)
