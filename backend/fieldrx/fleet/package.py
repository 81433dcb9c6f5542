"""Load a job's cells, rates, field and machine from PostGIS and build its JobPackage.

The package itself is built by ``fieldrx.formats.jobpackage.build_job_package``
(one definition of rounding and checksum); this module only gathers the rows.
"""

from __future__ import annotations

import numpy as np
from fieldrx_edge.protocol import JobPackage
from geoalchemy2.shape import to_shape
from sqlalchemy import select
from sqlalchemy.orm import Session

from fieldrx.agronomy.cells import CellTable
from fieldrx.db.models import (
    Field,
    Job,
    Machine,
    Plan,
    PlanCell,
    Prescription,
    PrescriptionRate,
    PrescriptionVersion,
)
from fieldrx.formats.jobpackage import build_job_package
from fieldrx.geo.crs import to_utm, utm_coords_to_lonlat


def job_rates(session: Session, job: Job) -> dict[int, float]:
    """seq -> planned rate of the job's prescription version."""
    rows = session.execute(
        select(PrescriptionRate.seq, PrescriptionRate.rate_kg_ha)
        .join(PrescriptionVersion, PrescriptionVersion.id == PrescriptionRate.version_id)
        .where(
            PrescriptionVersion.prescription_id == job.prescription_id,
            PrescriptionVersion.version == job.prescription_version,
        )
    ).all()
    return {int(s): float(r) for s, r in rows}


def load_package(session: Session, job: Job) -> JobPackage:
    rx = session.get(Prescription, job.prescription_id)
    assert rx is not None
    plan = session.get(Plan, rx.plan_id)
    assert plan is not None
    fld = session.get(Field, plan.field_id)
    machine = session.get(Machine, job.machine_id)
    assert fld is not None and machine is not None
    rates = job_rates(session, job)
    cells = session.execute(
        select(PlanCell.seq, PlanCell.swath, PlanCell.corners_utm)
        .where(PlanCell.plan_id == plan.id)
        .order_by(PlanCell.seq)
    ).all()
    n = len(cells)
    corners = np.asarray([c.corners_utm for c in cells], dtype=float).reshape(n, 4, 2)
    wgs = utm_coords_to_lonlat(corners.reshape(-1, 2), fld.utm_epsg).reshape(n, 4, 2)
    table = CellTable(
        epsg=fld.utm_epsg,
        seq=np.asarray([c.seq for c in cells]),
        swath=np.asarray([c.swath for c in cells]),
        polygons_utm=np.empty(n, dtype=object),
        centroids_utm=corners.mean(axis=1),
        corners_utm=corners,
        corners_wgs84=wgs,
        area_m2=np.zeros(n),
        rate_kg_ha=np.asarray([rates.get(int(c.seq), 0.0) for c in cells]),
    )
    boundary = to_utm(to_shape(fld.boundary), fld.utm_epsg)
    return build_job_package(
        table,
        boundary,
        job_id=job.id,
        machine_id=machine.id,
        prescription_id=rx.id,
        prescription_version=job.prescription_version,
        field_name=fld.name,
        implement_width_m=machine.width_m,
        lag_s=machine.lag_s,
        calibration=machine.calibration,
        controller=machine.controller or None,
        antenna_forward_m=machine.antenna_forward_m,
        antenna_lateral_m=machine.antenna_lateral_m,
        speed_min_m_s=machine.speed_min_m_s,
        speed_max_m_s=machine.speed_max_m_s,
        product=rx.product,
    )
