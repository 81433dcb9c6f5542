"""Seed 001 Table 1 layout: cell id, four corner lat/lon pairs, rate (path order).

Columns: ``cell_id, lat1, lon1, lat2, lon2, lat3, lon3, lat4, lon4, rate_kg_ha``
(latitude first, as in the paper's table; corners counter-clockwise, the
uncut cell rectangle), decimal degrees with 9 fraction digits.
"""

from __future__ import annotations

import csv
import io

from fieldrx.agronomy.cells import CellTable, flag_strings

HEADER = ["cell_id"] + [f"{a}{i}" for i in range(1, 5) for a in ("lat", "lon")] + ["rate_kg_ha"]


def write_table1_csv(cells: CellTable, include_flags: bool = False) -> bytes:
    """Table 1 CSV bytes; ``include_flags`` appends a ``flag`` column."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(HEADER + (["flag"] if include_flags else []))
    flags = flag_strings(cells.flags) if include_flags else None
    c = cells.corners_wgs84
    for i in range(len(cells)):
        row = [str(int(cells.seq[i]))]
        for k in range(4):
            row += [f"{c[i, k, 1]:.9f}", f"{c[i, k, 0]:.9f}"]
        row.append(f"{cells.rate_kg_ha[i]:.2f}")
        if flags is not None:
            row.append(flags[i])
        w.writerow(row)
    return buf.getvalue().encode()
