"""As-applied export timings for 100,000 record points: Shapefile, CSV and ISOXML writers.

A 10 Hz job of 100,000 records (2.8 h of work) over a 20 ha grid of 2.3 m x 5 m cells
(~17,400 cells): the per-cell polygons + the record points zipped as Shapefiles, the
per-cell CSV, and the TASKDATA.zip with its binary TimeLog. The writers are what an export
task runs after reading the job (``services.asapplied.export_job``); reading 100,000
telemetry rows is measured by bench/telemetry_query.py. Prints one line per format and a
JSON line at the end.

Run: nice .venv/bin/python bench/exports.py [n_points]
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np
from fieldrx.agronomy.cells import CellTable
from fieldrx.fleet.reports import CellReport, JobReport
from fieldrx.formats.asapplied import (
    AsAppliedPoints,
    AsAppliedTotals,
    CellRow,
    write_asapplied_isoxml,
    write_asapplied_shapefile_zip,
)
from fieldrx.services.asapplied import cells_csv

LIMIT_S = 15.0


def _points(n: int) -> AsAppliedPoints:
    rng = np.random.default_rng(0)
    t0 = 1_780_000_000.0
    return AsAppliedPoints(
        t=t0 + 0.1 * np.arange(n),
        lon=112.32 + rng.uniform(0, 0.004, n),
        lat=32.13 + rng.uniform(0, 0.004, n),
        target_kg_ha=rng.uniform(200, 400, n),
        applied_kg_ha=rng.uniform(200, 400, n),
        speed_m_s=rng.uniform(0.8, 2.5, n),
        down=rng.uniform(0, 1, n) > 0.05,
    )


def _report(cells: CellTable) -> JobReport:
    n = len(cells)
    rows = [
        CellReport(int(cells.seq[i]), int(cells.swath[i]), float(cells.area_m2[i]), 300.0,
                   6, 300.0, 298.0, 298.0, 345.0, 342.7, 99.3, 1.0, 2.0)
        for i in range(n)
    ]  # fmt: skip
    return JobReport(
        job_id=1, name="bench", state="completed", machine_id=1, implement_width_m=2.3,
        plan_id=1, n_cells=n, cells_planned=n, cells_applied=n, coverage_pct=100.0,
        planned_total_kg=1.0, applied_total_kg=1.0, applied_in_cells_kg=1.0,
        applied_outside_cells_kg=0.0, mean_accuracy_pct=99.0, min_accuracy_pct=98.0,
        time_worked_s=10_000.0, n_records=0, first_t=1.0, last_t=2.0, cells=rows,
    )  # fmt: skip


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 100_000
    cells = CellTable.rectangle(32649, 624000.0, 3556000.0, 174, 100, 2.3, 5.0)
    polys = cells.polygons_wgs84()
    rep = _report(cells)
    rows = [
        CellRow(c.seq, c.swath, c.n_records, c.area_m2, c.target_rate_kg_ha,
                c.applied_rate_kg_ha, c.m1_g, c.m2_g, c.accuracy_pct, polys[i])
        for i, c in enumerate(rep.cells)
    ]  # fmt: skip
    pts = _points(n)
    totals = AsAppliedTotals(1000.0, 200_000.0, 10_000.0, float(pts.t[0]), float(pts.t[-1]),
                             200_085.0)  # fmt: skip
    jobs = {
        "shapefile": lambda: write_asapplied_shapefile_zip("bench", rows, pts),
        "csv": lambda: cells_csv(rep),
        "isoxml": lambda: write_asapplied_isoxml(
            pts,
            totals,
            job_name="bench",
            field_name="bench",
            boundary_wgs84=None,
            product_name="urea",
        ),  # fmt: skip
    }
    out: dict[str, object] = {"points": n, "cells": len(cells), "limit_s": LIMIT_S}
    for name, fn in jobs.items():
        t = time.perf_counter()
        data = fn()
        s = time.perf_counter() - t
        out[f"{name}_s"] = round(s, 3)
        out[f"{name}_mb"] = round(len(data) / 1e6, 2)
        print(
            f"{name:10s} {s:7.2f} s  {len(data) / 1e6:7.2f} MB  {'ok' if s < LIMIT_S else 'SLOW'}"
        )
    out["all_under_limit"] = all(out[f"{k}_s"] < LIMIT_S for k in jobs)  # type: ignore[operator]
    print(json.dumps(out))


if __name__ == "__main__":
    main()
