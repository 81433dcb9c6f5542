"""Rate-zone dissolve (``formats.zones.dissolve_zones``) on the 500 ha bench field.

The planner bench's 500 ha field at real cell size (2.3 m swath x 5 m cells,
headland 2 passes, ~436k cells) with the smooth rate pattern of the zone tests
(200 + 80 sin(x/60) cos(y/45) kg/ha): the default export (8 classes, at most
100 polygons, FieldView's limit). Prints stage timings, what the sieve moved
(area, largest per-cell rate change) and the classes kept.
Run: .venv/bin/python bench/zones.py [swath_m cell_m [n_classes max_polygons]]

Measured on the 2-core machine under load 9..25 (435,729 cells, 8 classes, 100 polygons):
the old sieve (minimum patch doubled, full recomputation per round) 381.8 s, 2 zones /
8 polygons, 79.0 % of the area moved, largest rate change 81.8 kg/ha. Now 14.9..35 s
(union_all is ~85 % of it), 8 zones / 100 polygons, 69.0 % moved, 88.6 kg/ha: the rate
pattern has 734 connected class patches, so 100 polygons cannot draw 8 classes without
moving most of them; with 4 classes 36.5 % moves, with a limit of 1000 nothing moves.
"""

import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fieldrx.formats.zones import dissolve_zones  # noqa: E402
from fieldrx.geo.coverage import plan_coverage  # noqa: E402
from fieldrx.geo.grid import build_grid  # noqa: E402

from bench.planning import field_500ha  # noqa: E402


def main() -> None:
    args = sys.argv[1:]
    swath, cell = (float(args[0]), float(args[1])) if len(args) >= 2 else (2.3, 5.0)
    n_classes, max_polygons = (int(args[2]), int(args[3])) if len(args) >= 4 else (8, 100)
    f = field_500ha()
    t = time.perf_counter()
    plan = plan_coverage(f, swath_width_m=swath, headland_passes=2)
    c = build_grid(plan, f, cell_length_m=cell, epsg=32633)
    grid_s = time.perf_counter() - t
    xy = c.centroids_utm - c.centroids_utm.min(axis=0)
    c = c.with_rates(np.round(200 + 80 * np.sin(xy[:, 0] / 60) * np.cos(xy[:, 1] / 45), 1))
    print(f"cells: {len(c)}  area {c.total_area_m2 / 1e4:.1f} ha  grid {grid_s:.1f} s")
    t = time.perf_counter()
    zones, s = dissolve_zones(c, n_classes, max_polygons)
    dt = time.perf_counter() - t
    print(f"dissolve_zones: {dt:.1f} s")
    for z in zones:
        ha = z.area_m2 / 1e4
        print(f"  zone {z.rate_kg_ha:7.2f} kg/ha  {len(z.polygons):3d} polygons  {ha:8.2f} ha")
    print(s.note())
    result = {
        "n_cells": len(c),
        "field_ha": round(c.total_area_m2 / 1e4, 1),
        "swath_m": swath,
        "cell_m": cell,
        "grid_s": round(grid_s, 2),
        "dissolve_s": round(dt, 2),
        **s.to_dict(),
        "area_reassigned_pct": round(100 * s.area_reassigned_m2 / c.total_area_m2, 3),
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
