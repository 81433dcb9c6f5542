"""Prescription export timings on a 100k-cell grid, per format.

Baseline (same run): shapely.to_geojson of the same WGS84 polygons, the bare
cost of serialising the geometry once; each format's ratio to it is printed.
Run: .venv/bin/python bench/rx_exports.py [n_swaths n_per_swath]
"""

import json
import sys
import time

import numpy as np
import shapely
from fieldrx.agronomy.cells import CellTable
from fieldrx.agronomy.interpolate import interpolate_to_cells
from fieldrx.formats.csv_table import write_table1_csv
from fieldrx.formats.geojson import write_geojson
from fieldrx.formats.isoxml import write_isoxml_grid, write_isoxml_zones
from fieldrx.formats.jobpackage import JobPackageSpec, build_job_package
from fieldrx.formats.shapefile import write_shapefile_zip
from fieldrx_edge.metering import LinearCalibration


def main():
    ns, nper = (int(sys.argv[1]), int(sys.argv[2])) if len(sys.argv) > 2 else (200, 500)
    x0, y0 = 624000.0, 3556000.0
    cells = CellTable.rectangle(32649, x0, y0, ns, nper, 2.3, 5.0)
    n = len(cells)
    # a smooth soil-N field from 300 samples, IDW onto cells, rates rounded to 5 kg/ha classes
    rng = np.random.default_rng(0)
    lo, hi = cells.centroids_utm.min(axis=0), cells.centroids_utm.max(axis=0)
    xy = rng.uniform(lo, hi, size=(300, 2))
    z = 600 + 150 * np.sin((xy[:, 0] - x0) / 120) + 100 * np.cos((xy[:, 1] - y0) / 300)
    t = time.perf_counter()
    v = interpolate_to_cells("idw", cells.polygons_utm, cells.centroids_utm, xy, z).values
    interp_s = time.perf_counter() - t
    cells = cells.with_rates(np.round(v / 5) * 5)
    polys = cells.polygons_wgs84()
    t = time.perf_counter()
    shapely.to_geojson(polys)
    base = time.perf_counter() - t
    boundary = shapely.box(x0, y0, x0 + ns * 2.3, y0 + nper * 5.0)
    jobs = {
        "geojson": lambda: write_geojson(cells),
        "csv": lambda: write_table1_csv(cells),
        "shapefile": lambda: write_shapefile_zip(cells),
        "isoxml": lambda: write_isoxml_grid(cells),
        "isoxml-zones": lambda: write_isoxml_zones(cells),
        "job": lambda: build_job_package(
            cells,
            boundary,
            JobPackageSpec(
                job_id=1,
                machine_id=1,
                prescription_id=1,
                prescription_version=1,
                field_name="bench",
                implement_width_m=2.3,
                lag_s=1.52,
                calibration=LinearCalibration(),
            ),
        ).to_json(),
    }
    result = {"n_cells": n, "idw_s": round(interp_s, 3), "baseline_to_geojson_s": round(base, 3)}
    print(f"cells: {n}; IDW (300 samples): {interp_s:.2f} s; baseline to_geojson: {base:.2f} s")
    for name, fn in jobs.items():
        t = time.perf_counter()
        out = fn()
        dt = time.perf_counter() - t
        print(f"{name:13s} {dt:7.2f} s  x{dt / base:5.1f} baseline  {len(out) / n:7.1f} B/cell")
        result[f"{name}_s"] = round(dt, 3)
        result[f"{name}_ratio"] = round(dt / base, 2)
        result[f"{name}_bytes_per_cell"] = round(len(out) / n, 1)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
