"""Job package size per cell, raw and gzipped, against a Table 1 CSV baseline of the same cells.

Run: .venv/bin/python bench/jobpackage.py [n_swaths n_per_swath]
"""

import gzip
import json
import sys
import time

import numpy as np
import shapely
from fieldrx.agronomy.cells import CellTable
from fieldrx.formats.csv_table import write_table1_csv
from fieldrx.formats.jobpackage import JobPackageSpec, build_job_package, package_size
from fieldrx_edge.metering import LinearCalibration


def main():
    ns, nper = (int(sys.argv[1]), int(sys.argv[2])) if len(sys.argv) > 2 else (100, 200)
    x0, y0 = 624000.0, 3556000.0
    cells = CellTable.rectangle(32649, x0, y0, ns, nper, 2.3, 5.0)
    rng = np.random.default_rng(0)
    cells = cells.with_rates(np.round(rng.uniform(580, 880, len(cells)), 2))
    boundary = shapely.box(x0, y0, x0 + ns * 2.3, y0 + nper * 5.0)
    t = time.perf_counter()
    pkg = build_job_package(
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
    )
    s = package_size(pkg)
    build_s = time.perf_counter() - t
    csv_raw = write_table1_csv(cells)
    csv_gz = gzip.compress(csv_raw, mtime=0)
    n = len(cells)
    base = {"csv_bytes_per_cell_raw": len(csv_raw) / n, "csv_bytes_per_cell_gzip": len(csv_gz) / n}
    print(f"cells: {n}")
    raw, gz = s["bytes_per_cell_raw"], s["bytes_per_cell_gzip"]
    print(f"job package: {raw:.1f} B/cell raw, {gz:.1f} B/cell gzip")
    print(
        f"Table 1 CSV baseline: {base['csv_bytes_per_cell_raw']:.1f} B/cell raw, "
        f"{base['csv_bytes_per_cell_gzip']:.1f} B/cell gzip"
    )
    print(f"build + seal + serialise: {build_s:.2f} s")
    out = {
        **s,
        **base,
        "ratio_raw_vs_csv": s["bytes_per_cell_raw"] / base["csv_bytes_per_cell_raw"],
        "ratio_gzip_vs_csv": s["bytes_per_cell_gzip"] / base["csv_bytes_per_cell_gzip"],
        "build_s": build_s,
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
