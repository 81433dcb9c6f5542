"""Per-cell NDVI from imagery: area-weighted mean, valid share, nodata, any CRS."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
import shapely
from fieldrx.imagery import ImageryError
from fieldrx.imagery.stats import cell_ndvi
from pyproj import Transformer
from shapely import affinity
from shapely.geometry import box

from tests.imagery.rasters import UTM, X0, Y0, write_tiff

# write_tiff's NDVI runs 0.2 -> 0.8 linearly west -> east across bounds X0-10 .. X0+210.
W0, W1 = X0 - 10, X0 + 210


def _ndvi_at(x: np.ndarray) -> np.ndarray:
    return 0.2 + 0.6 * (x - W0) / (W1 - W0)


def _cells(n_across: int = 30, n_along: int = 8, angle: float = 30.0) -> np.ndarray:
    """2.3 m x 5 m cells, rotated, inside the field."""
    cells = []
    for i in range(n_across):
        for j in range(n_along):
            c = box(X0 + 20 + i * 5.0, Y0 + 20 + j * 7.0, X0 + 22.3 + i * 5.0, Y0 + 25 + j * 7.0)
            cells.append(affinity.rotate(c, angle, origin="centroid"))
    return np.array(cells, dtype=object)


def test_linear_ndvi_mean_is_value_at_centroid(tmp_path) -> None:
    """For NDVI linear in x, a cell's area-weighted mean equals NDVI at its centroid."""
    src = write_tiff(tmp_path / "n.tif", "ndvi")
    cells = _cells()
    stats = cell_ndvi(src, "ndvi", {"ndvi": 1}, cells, UTM)
    expected = _ndvi_at(shapely.get_x(shapely.centroid(cells)))
    assert np.nanmax(np.abs(stats.mean - expected)) < 0.003
    assert np.all(stats.valid_share == 1.0)
    assert stats.info["cells_without_data"] == 0


def test_multispectral_in_wgs84_matches(tmp_path) -> None:
    """(NIR - red) / (NIR + red) from a lon/lat raster gives the same per-cell NDVI."""
    tr = Transformer.from_crs(UTM, 4326, always_xy=True)
    w, s = tr.transform(W0, Y0 - 10)
    e, n = tr.transform(W1, Y0 + 110)
    src = write_tiff(
        tmp_path / "m.tif", "multispectral", crs=4326, bounds=(w, s, e, n), res=(e - w) / 440
    )
    cells = _cells()
    stats = cell_ndvi(src, "multispectral", {"red": 3, "nir": 4}, cells, UTM)
    expected = _ndvi_at(shapely.get_x(shapely.centroid(cells)))
    # a lon/lat grid is slightly skewed against UTM: a few mm of NDVI at most
    assert np.nanmax(np.abs(stats.mean - expected)) < 0.01


def test_nodata_half_cell_and_outside(tmp_path) -> None:
    """Nodata west of x = X0 + 100: a cell straddling it has ~50 % valid samples; a cell
    outside the raster has none; below min_valid_share the cell has no NDVI."""
    src = write_tiff(tmp_path / "n.tif", "ndvi", nodata=-9999.0)
    with rasterio.open(src, "r+") as ds:
        a = ds.read(1)
        cols = int((X0 + 100 - W0) / 0.5)
        a[:, :cols] = -9999.0
        ds.write(a, 1)
    straddle = box(X0 + 98, Y0 + 40, X0 + 102, Y0 + 50)
    east = box(X0 + 150, Y0 + 40, X0 + 154, Y0 + 50)
    outside = box(X0 + 400, Y0 + 40, X0 + 404, Y0 + 50)
    cells = np.array([straddle, east, outside], dtype=object)
    stats = cell_ndvi(src, "ndvi", {"ndvi": 1}, cells, UTM, min_valid_share=0.4)
    assert stats.valid_share[0] == pytest.approx(0.5, abs=0.05)
    assert stats.mean[0] == pytest.approx(_ndvi_at(np.array([X0 + 101.0]))[0], abs=0.003)
    assert stats.valid_share[1] == 1.0 and stats.valid_share[2] == 0.0
    assert np.isnan(stats.mean[2])
    strict = cell_ndvi(src, "ndvi", {"ndvi": 1}, cells, UTM, min_valid_share=0.9)
    assert np.isnan(strict.mean[0]) and not np.isnan(strict.mean[1])


def test_coarse_satellite_pixels_and_sliver(tmp_path) -> None:
    """10 m pixels under 2.3 m cells: each cell takes the pixel(s) under it, weighted by
    area; a 0.05 m sliver still gets the pixel under it."""
    src = write_tiff(tmp_path / "s2.tif", "ndvi", res=10.0)
    cell = box(X0 + 95, Y0 + 40, X0 + 105, Y0 + 45)  # half in each of two 10 m pixels
    sliver = box(X0 + 52, Y0 + 40, X0 + 52.05, Y0 + 45)
    stats = cell_ndvi(src, "ndvi", {"ndvi": 1}, np.array([cell, sliver], dtype=object), UTM)
    # pixels are sampled at their centres by write_tiff's linspace over 22 columns
    col_vals = np.linspace(0.2, 0.8, 22)
    assert stats.mean[0] == pytest.approx((col_vals[10] + col_vals[11]) / 2, abs=1e-4)
    assert stats.mean[1] == pytest.approx(col_vals[6], abs=1e-4)


def test_orthophoto_is_refused(tmp_path) -> None:
    src = write_tiff(tmp_path / "o.tif", "orthophoto")
    with pytest.raises(ImageryError, match="'ndvi' or 'multispectral'"):
        cell_ndvi(src, "orthophoto", {"r": 1, "g": 2, "b": 3}, _cells(2, 2), UTM)
