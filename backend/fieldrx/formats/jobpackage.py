"""Build the edge agent's ``JobPackage`` from prescription cells (seed 001 sec. 1.2, Table 1).

Cells go in path order with UTM corners (for the agent's metric cell lookup)
and WGS84 corners (display, cross-checks), rounded to what matters in the
field: 1 mm in UTM, 1e-8 degrees (about 1 mm) in WGS84, 0.01 kg/ha in rates.

Cells whose real (clipped or headland) polygon differs from their 4-corner
rectangle also get their shape (``JobPackage.shape_*``): field-edge, hole and
headland-ring cells, whose rectangles overlap their neighbours'. The same
``shaped_cells`` rule decides which cells the as-applied report locates by
polygon, so the tractor, the simulator and the report agree on cell borders.
"""

from __future__ import annotations

import gzip
import json
from dataclasses import dataclass, field
from typing import Any, TypedDict

import numpy as np
import shapely
from fieldrx_edge.job_package import ControllerSettings, JobPackage
from fieldrx_edge.jobkinds.registry import DEFAULT_KIND
from fieldrx_edge.metering import Calibration, calibration_from_dict

from fieldrx.agronomy.cells import CellTable
from fieldrx.formats import FormatError
from fieldrx.geo.cells import cut_edge_midpoints, round_coords


def _round_list(a: np.ndarray, decimals: int) -> list[float]:
    return [float(v) for v in np.round(np.asarray(a, dtype=float).ravel(), decimals).tolist()]


def _geojson_coords(geom: Any, decimals: int = 3) -> dict[str, Any]:
    if geom is None or geom.is_empty or geom.geom_type not in ("Polygon", "MultiPolygon"):
        raise FormatError("job package: boundary_utm must be a non-empty Polygon or MultiPolygon")
    g = round_coords(geom, decimals)
    return json.loads(shapely.to_geojson(g))


SHAPE_TOLERANCE = 0.005  # a cell is "shaped" when polygon and rectangle differ by > 0.5 %
# a cell whose polygon lies beside its driving line is located by its rectangle when the
# polygon is at least this fraction of it (the grid's own smallest worthwhile cell)
BESIDE_LINE_MIN_FRACTION = 0.1


def shaped_cells(
    polygons_utm: Any, corners_utm: np.ndarray, tolerance: float = SHAPE_TOLERANCE
) -> np.ndarray:
    """Mask of cells whose polygon differs from its rectangle by more than ``tolerance``
    of the rectangle's area (symmetric difference: a moved cell of equal area counts).

    Interior cells are the rectangle itself (4 vertices within 1 cm of the corners,
    checked with numpy); only the others are compared with shapely.
    """
    polys = np.asarray(polygons_utm, dtype=object)
    c = np.asarray(corners_utm, dtype=float).reshape(-1, 4, 2)
    n = len(c)
    out = np.zeros(n, dtype=bool)
    if n == 0:
        return out
    simple = (
        (shapely.get_type_id(polys) == 3)
        & (shapely.get_num_interior_rings(polys) == 0)
        & (shapely.get_num_coordinates(polys) == 5)
    )
    same = np.zeros(n, dtype=bool)
    if simple.any():
        v = shapely.get_coordinates(shapely.get_exterior_ring(polys[simple])).reshape(-1, 5, 2)
        d = np.linalg.norm(v[:, :4, None, :] - c[simple][:, None, :, :], axis=-1)
        same[simple] = (d.min(axis=2) < 0.01).all(axis=1) & (d.min(axis=1) < 0.01).all(axis=1)
    rest = np.flatnonzero(~same)
    if len(rest):
        quads = shapely.polygons(c[rest])
        diff = shapely.area(shapely.symmetric_difference(shapely.make_valid(polys[rest]), quads))
        out[rest] = diff > tolerance * np.maximum(shapely.area(quads), 1e-9)
    out[beside_line_cells(polys, c, out)] = False
    return out


def beside_line_cells(polys: Any, c: np.ndarray, shaped: np.ndarray) -> np.ndarray:
    """Shaped cells whose polygon misses their own driving line but fills at least
    ``BESIDE_LINE_MIN_FRACTION`` of their rectangle.

    Tractor, simulator and report put the metered mass at a point on the driving
    line (seed 001 sec. 2.3, eq. 16) and look that point up in the cells. A swath
    that overlaps the headland ring by more than half the implement width (the last
    inner swath when the inner width is not a multiple of it: 12 m on a
    ~100 m field) has cells whose polygon is only the strip beside the line: the
    point is then always in the (finished) ring cell and the swath was never metered.
    Driving that line with the implement down is the only way to cover the strip,
    so such a cell is located by its rectangle (the implement's footprint) and its
    theoretical mass is the footprint's (eq. 17: driven length x implement width).
    A sliver below the fraction keeps its shape: covering it would double-apply a
    whole footprint, so it stays unapplied and the job-end alert lists it.
    """
    polys = np.asarray(polys, dtype=object)
    c = np.asarray(c, dtype=float).reshape(-1, 4, 2)
    out = np.zeros(len(c), dtype=bool)
    idx = np.flatnonzero(shaped)
    if len(idx) == 0:
        return out
    cc = c[idx]
    rear, front = cut_edge_midpoints(cc)  # the one driving-line rule
    lines = shapely.linestrings(np.stack([rear, front], axis=1))
    real = shapely.make_valid(polys[idx])
    on_line = shapely.length(shapely.intersection(lines, real))
    frac = shapely.area(real) / np.maximum(shapely.area(shapely.polygons(cc)), 1e-9)
    out[idx] = (on_line <= 0.01 * shapely.length(lines)) & (frac >= BESIDE_LINE_MIN_FRACTION)
    return out


class _ShapeFields(TypedDict, total=False):
    """The ``JobPackage.shape_*`` arguments (none when no cell is shaped)."""

    shape_seq: list[int]
    shape_ring_offsets: list[int]
    shape_offsets: list[int]
    shape_xy_utm: list[float]


def _shape_fields(cells: CellTable, decimals: int) -> _ShapeFields:
    """``JobPackage.shape_*`` for the shaped cells: rings of every polygon part, open, rounded."""
    mask = shaped_cells(cells.polygons_utm, cells.corners_utm)
    seqs: list[int] = []
    ring_off = [0]
    vert_off = [0]
    xy: list[float] = []
    for i in np.flatnonzero(mask):
        g = cells.polygons_utm[i]
        parts = list(g.geoms) if g.geom_type == "MultiPolygon" else [g]
        n_rings = 0
        for poly in parts:
            if poly.geom_type != "Polygon" or poly.is_empty:
                continue
            for ring in (poly.exterior, *poly.interiors):
                pts = np.round(np.asarray(ring.coords, dtype=float)[:-1, :2], decimals)
                if len(pts) < 3:
                    continue
                xy.extend(float(v) for v in pts.ravel().tolist())
                vert_off.append(vert_off[-1] + len(pts))
                n_rings += 1
        if n_rings:
            seqs.append(int(cells.seq[i]))
            ring_off.append(ring_off[-1] + n_rings)
    if not seqs:
        return _ShapeFields()
    return {
        "shape_seq": seqs,
        "shape_ring_offsets": ring_off,
        "shape_offsets": vert_off,
        "shape_xy_utm": xy,
    }


@dataclass(frozen=True)
class JobPackageSpec:
    """Everything in a job package beside the cells and the boundary: the job's ids, the
    machine's part (``services.jobpackage.machine_fields``), the product and the job kind.
    ``calibration`` is a ``fieldrx_edge.metering`` calibration or its dict form."""

    job_id: int
    machine_id: int
    prescription_id: int
    prescription_version: int
    field_name: str
    implement_width_m: float
    lag_s: float
    calibration: Calibration | dict[str, Any]
    controller: ControllerSettings | dict[str, Any] | None = None
    antenna_forward_m: float = 0.0
    antenna_lateral_m: float = 0.0
    speed_min_m_s: float = 0.8
    speed_max_m_s: float = 2.5
    product: str = ""
    kind: str = DEFAULT_KIND
    kind_settings: dict[str, Any] | None = None
    rate_unit: str = "kg/ha"
    product_density_kg_l: float = 0.0
    unit_lot: dict[str, float] = field(default_factory=dict)


def build_job_package(
    cells: CellTable,
    boundary_utm: Any,
    spec: JobPackageSpec,
    *,
    utm_decimals: int = 3,
    wgs84_decimals: int = 8,
    shape_decimals: int = 6,
) -> JobPackage:
    """A sealed (validated, checksummed) JobPackage; ``ProtocolError`` names a bad field.

    ``boundary_utm`` is a shapely (Multi)Polygon in ``cells.epsg``.
    Shapes keep 1 um (``shape_decimals``): neighbouring real cells share clipped edges
    whose vertices differ, and 1 mm rounding would make them overlap by ~1e-3 m^2
    slivers (1e-4 of a cell); at 1 um the overlap stays below 1e-6 of a cell.
    """
    calibration, controller = spec.calibration, spec.controller
    cal = calibration if isinstance(calibration, dict) else calibration.to_dict()  # type: ignore[attr-defined]
    try:
        cal = calibration_from_dict(dict(cal)).to_dict()  # validated, complete
    except (KeyError, TypeError, ValueError) as exc:
        raise FormatError(f"job package: bad calibration ({exc})") from exc
    if controller is None:
        ctl = ControllerSettings()
    elif isinstance(controller, dict):
        try:
            ctl = ControllerSettings(**controller)
        except TypeError as exc:
            raise FormatError(f"job package: bad controller settings ({exc})") from exc
    else:
        ctl = controller
    pkg = JobPackage(
        job_id=int(spec.job_id),
        machine_id=int(spec.machine_id),
        prescription_id=int(spec.prescription_id),
        prescription_version=int(spec.prescription_version),
        field_name=str(spec.field_name),
        utm_epsg=int(cells.epsg),
        implement_width_m=float(spec.implement_width_m),
        lag_s=float(spec.lag_s),
        calibration=dict(cal),
        controller=ctl,
        boundary_utm=_geojson_coords(boundary_utm, utm_decimals),
        seq=[int(s) for s in cells.seq.tolist()],
        swath=[int(s) for s in cells.swath.tolist()],
        rate_kg_ha=_round_list(cells.rate_kg_ha, 2),
        corners_utm=_round_list(cells.corners_utm, utm_decimals),
        corners_wgs84=_round_list(cells.corners_wgs84, wgs84_decimals),
        antenna_forward_m=float(spec.antenna_forward_m),
        antenna_lateral_m=float(spec.antenna_lateral_m),
        speed_min_m_s=float(spec.speed_min_m_s),
        speed_max_m_s=float(spec.speed_max_m_s),
        product=str(spec.product),
        **_shape_fields(cells, shape_decimals),
        kind=spec.kind,
        kind_settings=dict(spec.kind_settings or {}),
        rate_unit=str(spec.rate_unit),
        product_density_kg_l=float(spec.product_density_kg_l),
        unit_lot=dict(spec.unit_lot),
    )
    return pkg.seal()


def package_size(pkg: JobPackage) -> dict[str, float]:
    """Bytes of the package JSON as served, raw and gzipped, total and per cell."""
    raw = pkg.to_json()
    gz = gzip.compress(raw, compresslevel=6, mtime=0)
    n = max(1, pkg.n_cells)
    return {
        "n_cells": pkg.n_cells,
        "bytes_raw": len(raw),
        "bytes_gzip": len(gz),
        "bytes_per_cell_raw": len(raw) / n,
        "bytes_per_cell_gzip": len(gz) / n,
    }


def package_etag(pkg: JobPackage) -> str:
    """Strong ETag: the package checksum (SHA-256 of its canonical JSON)."""
    if not pkg.checksum:
        pkg.seal()
    return f'"{pkg.checksum}"'
