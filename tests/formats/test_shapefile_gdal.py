"""The acceptance test: every Shapefile export of the bench fields is valid in GDAL/OGR.

GDAL reads a Shapefile polygon as a list of rings and decides which ring is an
exterior and which a hole from the ring winding (clockwise = exterior, ESRI
Shapefile Technical Description 1998, p. 8). So the check reads each export with
OGR (through pyogrio, GDAL's own shapefile driver), asks GDAL's GEOS-backed
``ST_IsValid`` about every geometry (SQLite SQL dialect), and fails on any
warning or error GDAL prints (GEOS "Hole lies outside shell", "Self-intersection",
ring organisation warnings) or raises. It then compares OGR's assembly with the
rings as written (pyshp): the same polygon and hole count per record and the same
area. A file with a mis-wound ring fails this check (see the control test).

Fields: the planner bench's fields (``bench/planning.py``: the 10 ha rectangle, L,
U, the field with a pond, the irregular 40-vertex field at 2.3 m x 5 m cells, and
the 500 ha field at 12 m x 10 m cells, 42,016 cells, to keep the test's time
reasonable).
"""

from __future__ import annotations

import io
import sys
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
import shapefile as pyshp
import shapely
from fieldrx.agronomy.cells import CellTable
from fieldrx.formats.asapplied import AsAppliedPoints, CellRow, write_asapplied_shapefile_zip
from fieldrx.formats.shapefile import write_shapefile_zip, write_shapefile_zones_zip
from fieldrx.geo.coverage import plan_coverage
from fieldrx.geo.grid import build_grid

from tests.geo.cases import irregular, l_shape, pond_field, rect, u_shape

pyogrio = pytest.importorskip("pyogrio")
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from bench.planning import field_500ha  # noqa: E402

EPSG = 32633  # tests.geo.cases are UTM 33N metres
SMALL = {"rect_10ha": rect, "L": l_shape, "U": u_shape, "pond": pond_field, "irregular": irregular}


def bench_cells(field, w: float = 2.3, length: float = 5.0, epsg: int = EPSG) -> CellTable:
    plan = plan_coverage(field, swath_width_m=w, headland_passes=2)
    c = build_grid(plan, field, cell_length_m=length, epsg=epsg)
    xy = c.centroids_utm - c.centroids_utm.min(axis=0)
    r = 200 + 80 * np.sin(xy[:, 0] / 60) * np.cos(xy[:, 1] / 45)
    return c.with_rates(np.round(r, 1))


def _shapefiles(data: bytes, tmp_path: Path) -> list[Path]:
    d = tmp_path / f"x{len(list(tmp_path.iterdir()))}"
    zipfile.ZipFile(io.BytesIO(data)).extractall(d)
    return sorted(d.rglob("*.shp"))


def ogr_problems(shp: Path, capfd) -> list[str]:
    """What GDAL objects to in one Shapefile (empty list = clean); see module docstring."""
    capfd.readouterr()
    problems: list[str] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        meta, _, wkb, _ = pyogrio.raw.read(shp)
        layer = meta["layer_name"] if "layer_name" in meta else shp.stem
        _, _, _, (valid,) = pyogrio.raw.read(
            shp, sql=f'SELECT ST_IsValid(geometry) AS v FROM "{layer}"', sql_dialect="SQLITE"
        )
    problems += [f"python warning: {w.message}" for w in caught]
    err = capfd.readouterr().err
    problems += [f"gdal: {line}" for line in err.splitlines() if line.strip()]
    bad = np.flatnonzero(np.asarray(valid) != 1)
    problems += [f"record {i}: GDAL ST_IsValid = {valid[i]}" for i in bad[:5]]
    if meta["geometry_type"] not in ("Polygon", "MultiPolygon", "Point"):
        problems.append(f"geometry type {meta['geometry_type']}")
    if meta["geometry_type"] == "Point":
        return problems
    ogr = shapely.from_wkb(wkb)
    written = [shapely.geometry.shape(s.__geo_interface__) for s in pyshp.Reader(str(shp)).shapes()]
    if len(written) != len(ogr):
        return [*problems, f"{len(ogr)} OGR features, {len(written)} records written"]
    for i, (g, w) in enumerate(zip(ogr, written, strict=True)):
        gp, wp = shapely.get_parts(g), shapely.get_parts(w)
        holes = (sorted(len(p.interiors) for p in gp), sorted(len(p.interiors) for p in wp))
        if len(gp) != len(wp) or holes[0] != holes[1]:
            problems.append(f"record {i}: OGR assembled {len(gp)} parts / holes {holes[0]}")
        elif not np.isclose(g.area, w.area, rtol=1e-9, atol=0):
            problems.append(f"record {i}: OGR area {g.area} != written {w.area}")
        if len(problems) > 10:
            break
    return problems


def test_control_miswound_rings_are_caught(tmp_path, capfd):
    """The check has teeth: exterior counter-clockwise + hole clockwise (a reversed writer)."""
    p = tmp_path / "bad"
    with pyshp.Writer(str(p), shapeType=pyshp.POLYGON) as w:
        w.field("ID", "N", 4, 0)
        w.poly(
            [[(0, 0), (10, 0), (10, 10), (0, 10), (0, 0)], [(2, 2), (2, 4), (4, 4), (4, 2), (2, 2)]]
        )
        w.record(1)
    problems = ogr_problems(p.with_suffix(".shp"), capfd)
    assert problems, "a reversed-winding polygon must be reported"
    assert any("ST_IsValid = 0" in s for s in problems), problems
    assert any(s.startswith("gdal:") and "Hole lies outside shell" in s for s in problems), problems


def _asapplied_zip(c: CellTable) -> bytes:
    polys = c.polygons_wgs84()
    rows = [
        CellRow(
            int(c.seq[i]),
            int(c.swath[i]),
            3,
            float(c.area_m2[i]),
            float(c.rate_kg_ha[i]),
            float(c.rate_kg_ha[i]) * 1.02,
            1.0,
            1.02,
            2.0,
            polys[i],
        )
        for i in range(len(c))
    ]
    pts = shapely.get_coordinates(shapely.centroid(polys[:200]))
    n = len(pts)
    points = AsAppliedPoints(
        t=1.7e9 + np.arange(n, dtype=float),
        lon=pts[:, 0],
        lat=pts[:, 1],
        target_kg_ha=np.full(n, 200.0),
        applied_kg_ha=np.full(n, 204.0),
        speed_m_s=np.full(n, 2.0),
        down=np.ones(n, dtype=bool),
    )
    return write_asapplied_shapefile_zip("asapplied", rows, points)


def _all_exports(c: CellTable, zone_profiles: tuple[str, ...]) -> dict[str, bytes]:
    out = {"cells": write_shapefile_zip(c, "rx"), "asapplied": _asapplied_zip(c)}
    for prof in zone_profiles:
        out[f"zones-{prof}"] = write_shapefile_zones_zip(c, "rx", prof, n_classes=8)[0]
    return out


@pytest.mark.parametrize("name", sorted(SMALL))
def test_bench_field_exports_clean_in_gdal(name, tmp_path, capfd):
    c = bench_cells(SMALL[name]())
    report = {}
    for kind, data in _all_exports(c, ("deere", "fieldview")).items():
        for shp in _shapefiles(data, tmp_path):
            report[f"{kind}/{shp.name}"] = ogr_problems(shp, capfd)
    assert not any(report.values()), {k: v for k, v in report.items() if v}
    assert len(report) == 5  # cells, as-applied cells + points, two zone profiles


@pytest.mark.timeout(600)
def test_500ha_field_exports_clean_in_gdal(tmp_path, capfd):
    c = bench_cells(field_500ha(), w=12.0, length=10.0)
    assert len(c) > 40_000
    report = {}
    for kind, data in _all_exports(c, ("fieldview",)).items():
        for shp in _shapefiles(data, tmp_path):
            report[f"{kind}/{shp.name}"] = ogr_problems(shp, capfd)
    assert not any(report.values()), {k: v for k, v in report.items() if v}
