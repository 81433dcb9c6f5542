"""The job's own geometry for the cab map and its guidance: cells, boundary and planned
swath lines in local metres (UTM minus an origin), straight from the cached job package.

Guidance follows the planned path (seed 001's boustrophedon: each swath a straight line
through its cells' centres, driven in path order): the cross-track error is the signed
distance of the antenna to the current swath's line (positive: right of the line in the
driving direction, so steer left), the distance to the next turn is what is left of the
swath ahead along that line.
"""

from __future__ import annotations

import math
from typing import Any

from fieldrx_edge.gnss.utm import UtmProjection
from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.metering import calibration_from_dict


def _ring_area(xy: list[float]) -> float:
    n = len(xy) // 2
    s = 0.0
    for i in range(n):
        x0, y0 = xy[2 * i], xy[2 * i + 1]
        x1, y1 = xy[2 * ((i + 1) % n)], xy[2 * ((i + 1) % n) + 1]
        s += x0 * y1 - x1 * y0
    return abs(s) / 2.0


class JobGeometry:
    def __init__(self, job: JobPackage) -> None:
        self.job = job
        self.proj = UtmProjection(job.utm_epsg)
        c = job.corners_utm
        self.ox = min(c[0::2]) if c else 0.0
        self.oy = min(c[1::2]) if c else 0.0
        shapes = job.cell_shapes()
        self.index = {int(s): i for i, s in enumerate(job.seq)}
        self.rings: list[list[list[float]]] = []
        self.areas: list[float] = []
        for i in range(len(job.seq)):
            rings = shapes.get(i) or [c[8 * i : 8 * i + 8]]
            self.rings.append(rings)
            outer = max(rings, key=_ring_area)
            self.areas.append(
                _ring_area(outer) - sum(_ring_area(r) for r in rings if r is not outer)
            )
        self.total_area = sum(a for a, r in zip(self.areas, job.rate_kg_ha, strict=True) if r > 0)
        if job.kind != "prescription_map":
            self.total_area = sum(self.areas)
        cal = calibration_from_dict(job.calibration)
        self.min_rpm, self.max_rpm = float(cal.min_rpm), float(cal.max_rpm)
        self.lines = self._swath_lines()

    def _swath_lines(self) -> dict[int, tuple[float, float, float, float]]:
        """Swath -> (x0, y0, x1, y1): the line through its first and last cells' centres,
        in the driving direction (path order)."""
        c = self.job.corners_utm
        first: dict[int, int] = {}
        last: dict[int, int] = {}
        for i, s in enumerate(self.job.swath):
            first.setdefault(int(s), i)
            last[int(s)] = i

        def centre(i: int) -> tuple[float, float]:
            q = c[8 * i : 8 * i + 8]
            return sum(q[0::2]) / 4.0, sum(q[1::2]) / 4.0

        out = {}
        for s, i in first.items():
            (x0, y0), (x1, y1) = centre(i), centre(last[s])
            out[s] = (x0, y0, x1, y1)
        return out

    def area_of(self, seqs: set[int]) -> float:
        return sum(self.areas[self.index[s]] for s in seqs if s in self.index)

    def local(self, rec: dict[str, Any]) -> tuple[float, float]:
        """The record's position in UTM (the map's local metres are these minus the origin)."""
        return self.proj.forward(rec["lon"], rec["lat"])

    def guidance(self, rec: dict[str, Any], x: float, y: float) -> dict[str, Any] | None:
        """Cross-track error to the current swath's line and distance to its end."""
        cell = rec.get("cell_seq")
        swath = self.job.swath[self.index[cell]] if cell in self.index else None
        if swath is None:
            swath = self._nearest_swath(x, y)
        if swath is None:
            return None
        x0, y0, x1, y1 = self.lines[int(swath)]
        dx, dy = x1 - x0, y1 - y0
        length = math.hypot(dx, dy)
        if length < 1e-6:
            return None
        ux, uy = dx / length, dy / length
        along = (x - x0) * ux + (y - y0) * uy
        # right of the line in the driving direction is positive (cross product sign)
        xte = (x - x0) * uy - (y - y0) * ux
        return {
            "swath": int(swath),
            "xte_m": xte,
            "steer": "left" if xte > 0.05 else "right" if xte < -0.05 else "on line",
            "to_turn_m": max(0.0, length - along),
            "turn_at": [x1 - self.ox, y1 - self.oy],
        }

    def _nearest_swath(self, x: float, y: float) -> int | None:
        best, best_d = None, math.inf
        for s, (x0, y0, x1, y1) in self.lines.items():
            dx, dy = x1 - x0, y1 - y0
            n = math.hypot(dx, dy) or 1.0
            d = abs((x - x0) * dy - (y - y0) * dx) / n
            if d < best_d:
                best, best_d = s, d
        return best

    def to_json(self) -> dict[str, Any]:
        """What the page draws: cells (local metres, rings), rates, path order, boundary."""
        ox, oy = self.ox, self.oy

        def local(xy: list[float]) -> list[float]:
            return [round(v - (ox if k % 2 == 0 else oy), 2) for k, v in enumerate(xy)]

        def ring_list(geom: dict[str, Any]) -> list[list[float]]:
            polys = (
                geom["coordinates"]
                if geom.get("type") == "MultiPolygon"
                else [geom.get("coordinates", [])]
            )
            return [local([v for pt in ring for v in pt[:2]]) for poly in polys for ring in poly]

        job = self.job
        return {
            "job_id": job.job_id,
            "kind": job.kind,
            "field": job.field_name,
            "product": job.product,
            "prescription_version": job.prescription_version,
            "width_m": job.implement_width_m,
            "seq": list(job.seq),
            "swath": list(job.swath),
            "rate": list(job.rate_kg_ha),
            "cells": [[local(r) for r in rings] for rings in self.rings],
            "boundary": ring_list(job.boundary_utm),
            "lines": {
                str(s): [x0 - ox, y0 - oy, x1 - ox, y1 - oy]
                for s, (x0, y0, x1, y1) in self.lines.items()
            },
            "speed_band_m_s": [job.speed_min_m_s, job.speed_max_m_s],
            "meter_rpm": [self.min_rpm, self.max_rpm],
            "kind_settings": job.kind_settings,
        }
