"""The one cell type (CellTable = geo.cells.Cells): the real geo grid, WGS84 round trip,
test rectangles."""

import numpy as np
import pytest
import shapely
from fieldrx.agronomy.cells import CellTable
from fieldrx.agronomy.interpolate import cell_mean
from fieldrx.formats import FormatError
from fieldrx.formats.export import export_prescription
from fieldrx.geo.coverage import plan_coverage
from fieldrx.geo.crs import to_utm, to_wgs84
from fieldrx.geo.grid import build_grid

EPSG = 32649
X0, Y0 = 624000.0, 3556000.0


def _real_cells():
    field = shapely.Polygon([(X0, Y0), (X0 + 60, Y0 + 5), (X0 + 55, Y0 + 40), (X0, Y0 + 35)])
    plan = plan_coverage(field, swath_width_m=2.3, heading="longest_edge")
    grid = build_grid(plan, field, cell_length_m=5.0, epsg=EPSG)
    return field, grid, grid


def test_from_real_grid_keeps_path_order_and_area():
    field, grid, cells = _real_cells()
    assert len(cells) == len(grid)
    np.testing.assert_array_equal(cells.seq, grid.seq)
    assert cells.total_area_m2 == pytest.approx(field.area, rel=1e-6)
    assert cells.corners_wgs84.shape == (len(cells), 4, 2)
    # corners counter-clockwise in WGS84 too
    x, y = cells.corners_wgs84[..., 0], cells.corners_wgs84[..., 1]
    signed = 0.5 * np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)
    assert (signed > 0).all()


def test_five_point_sampling_on_real_grid():
    _, _, cells = _real_cells()
    # seed 001: centre + 4 corners of every cell, value = cell index; each cell gets its own
    # centre plus the corner samples it shares with its neighbours
    i = len(cells) // 2
    pts = np.vstack([cells.centroids_utm[i], cells.corners_utm[i]])
    res = cell_mean(cells.polygons_utm, pts, np.full(5, 42.0))
    assert res.values[i] == 42.0 and not res.no_data[i]


def test_from_polygons_wgs84_roundtrip():
    ref = CellTable.rectangle(EPSG, X0, Y0, 3, 4, 2.3, 5.0)
    wgs = to_wgs84(ref.polygons_utm, EPSG)
    back = CellTable.from_polygons_utm(EPSG, ref.seq, ref.swath, to_utm(wgs, EPSG))
    np.testing.assert_allclose(back.area_m2, ref.area_m2, rtol=1e-6)
    np.testing.assert_allclose(back.centroids_utm, ref.centroids_utm, atol=1e-6)
    # corners recovered from the polygon (oriented envelope), as a set per cell
    for a, b in zip(back.corners_utm, ref.corners_utm, strict=True):
        d = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
        assert (d.min(axis=1) < 1e-3).all() and (d.min(axis=0) < 1e-3).all()
    with_corners = CellTable.from_polygons_utm(
        EPSG, ref.seq, ref.swath, to_utm(wgs, EPSG), ref.corners_utm
    )
    np.testing.assert_allclose(with_corners.corners_utm, ref.corners_utm, atol=1e-6)


def test_export_dispatcher():
    cells = CellTable.rectangle(EPSG, X0, Y0, 2, 2).with_rates(np.array([1.0, 2.0, 3.0, 4.0]))
    data, media, name = export_prescription(cells, "csv")
    assert media == "text/csv" and name.endswith(".csv") and data.count(b"\n") == 5
    with pytest.raises(FormatError, match="unknown export format"):
        export_prescription(cells, "pdf")
