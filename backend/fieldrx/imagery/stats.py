"""Per-cell raster statistics: the area-weighted mean NDVI of each grid cell.

Method. The cells' polygons are moved into the raster's CRS and burnt
into a label grid (GDAL rasterize, one label per cell, a sample belongs to the cell that
contains its centre) laid over the cells' extent at a sampling step of a tenth of a
typical cell's side (coarser only to stay under ``max_samples``). The raster is read onto
the same grid: nearest neighbour when its pixels are coarser than the step, so each pixel
contributes in proportion to the part of it inside the cell; GDAL's average (over
overviews where they exist) when they are finer. Every sample covers the same area,
so a cell's plain mean over its samples is the area-weighted mean of the pixels under it,
to within one sampling step along the cell's edge.

NDVI = (NIR - red) / (NIR + red) for multispectral images (seed 000 uses canopy NDVI the
same way); a stored NDVI band is used as it is. Nodata, the dataset mask (clouds masked
upstream), non-finite values, NIR + red <= 0 and NDVI outside [-1, 1] are invalid. Each
cell gets the share of its samples that were valid; below ``min_valid_share`` its NDVI is
NaN (no data), so the prescription's fallback applies and the cell is flagged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fieldrx.imagery import ImageryError

SAMPLES_PER_SIDE = 10
MAX_SAMPLES = 80_000_000


@dataclass
class CellStats:
    """Per cell (path order): mean NDVI (NaN = no data) and the share of valid samples."""

    mean: np.ndarray
    valid_share: np.ndarray
    info: dict[str, Any] = field(default_factory=dict)


def _to_raster_crs(polys: np.ndarray, utm_epsg: int, crs: Any) -> np.ndarray:
    import shapely
    from pyproj import CRS, Transformer

    if CRS.from_user_input(crs) == CRS.from_epsg(utm_epsg):
        return polys
    tr = Transformer.from_crs(utm_epsg, CRS.from_user_input(crs), always_xy=True)

    def move(xy: np.ndarray) -> np.ndarray:
        x, y = tr.transform(xy[:, 0], xy[:, 1])
        return np.column_stack([x, y])

    return shapely.transform(polys, move)


def _ndvi(
    src: Any, kind: str, bands: dict[str, int], window: Any, shape: tuple[int, int], resampling: Any
) -> np.ndarray:
    """NDVI on the sampling grid as float32, NaN where invalid."""
    from rasterio.windows import Window

    idx = [bands["ndvi"]] if kind == "ndvi" else [bands["red"], bands["nir"]]
    inside = (
        window.intersection(Window(0, 0, src.width, src.height)) if _overlaps(window, src) else None
    )
    out = np.full(shape, np.nan, dtype="float32")
    if inside is None:
        return out
    # Read only the part of the grid the raster covers (a boundless read goes through a
    # warped VRT and is several times slower); the rest stays NaN.
    sy = shape[0] / window.height
    sx = shape[1] / window.width
    r0 = int(round((inside.row_off - window.row_off) * sy))
    c0 = int(round((inside.col_off - window.col_off) * sx))
    h = min(shape[0] - r0, max(1, int(round(inside.height * sy))))
    w = min(shape[1] - c0, max(1, int(round(inside.width * sx))))
    data = src.read(
        idx, window=inside, out_shape=(len(idx), h, w), masked=True, resampling=resampling
    )
    mask = np.ma.getmaskarray(data).any(axis=0)
    arr = np.asarray(data.data, dtype="float32")
    if kind == "ndvi":
        val = arr[0]
    else:
        red, nir = arr
        den = nir + red
        with np.errstate(divide="ignore", invalid="ignore"):
            val = (nir - red) / den
        mask |= ~(den > 0)
    with np.errstate(invalid="ignore"):
        mask |= ~((val >= -1.0) & (val <= 1.0))  # also catches NaN and inf
    val[mask] = np.nan
    out[r0 : r0 + h, c0 : c0 + w] = val
    return out


def _overlaps(window: Any, src: Any) -> bool:
    return (
        window.col_off < src.width
        and window.row_off < src.height
        and window.col_off + window.width > 0
        and window.row_off + window.height > 0
    )


def _shapes(polys: np.ndarray) -> list[Any]:
    """GeoJSON-like shapes for GDAL rasterize, built from packed coordinates (shapely's
    per-object ``__geo_interface__`` costs ~50 us per cell); polygons with holes and
    multipolygons keep their own interface."""
    import shapely

    simple = (shapely.get_type_id(polys) == 3) & (shapely.get_num_interior_rings(polys) == 0)
    coords = shapely.get_coordinates(polys).tolist()  # one conversion, then list slices
    counts = shapely.get_num_coordinates(polys)
    ends = np.cumsum(counts).tolist()
    starts = (np.cumsum(counts) - counts).tolist()
    flags = simple.tolist()
    return [
        {"type": "Polygon", "coordinates": [coords[a:b]]} if ok else g
        for a, b, ok, g in zip(starts, ends, flags, polys, strict=True)
    ]


def cell_ndvi(
    path: Path,
    kind: str,
    bands: dict[str, int],
    polygons_utm: np.ndarray,
    utm_epsg: int,
    *,
    min_valid_share: float = 0.5,
    max_samples: int = MAX_SAMPLES,
) -> CellStats:
    """Area-weighted mean NDVI and valid share of every cell polygon (UTM metres)."""
    import rasterio
    import shapely
    from rasterio.enums import Resampling
    from rasterio.features import rasterize
    from rasterio.transform import from_origin
    from rasterio.windows import from_bounds

    if kind not in ("ndvi", "multispectral"):
        raise ImageryError(f"NDVI needs an 'ndvi' or 'multispectral' image, this one is {kind!r}")
    if not 0.0 <= min_valid_share <= 1.0:
        raise ImageryError(f"min_valid_share must be in [0, 1], got {min_valid_share!r}")
    polys_utm = np.asarray(polygons_utm, dtype=object)
    n = len(polys_utm)
    if n == 0:
        return CellStats(np.zeros(0), np.zeros(0), {"cells": 0})
    areas = shapely.area(polys_utm)
    typical_side = math.sqrt(float(np.median(areas[areas > 0])) if np.any(areas > 0) else 1.0)
    with rasterio.open(path) as src:
        polys = _to_raster_crs(polys_utm, utm_epsg, src.crs)
        minx, miny, maxx, maxy = shapely.total_bounds(polys)
        # Sampling step in raster units: typical side / 10 measured in the raster's CRS.
        scale = math.sqrt(float(shapely.area(polys).sum()) / max(float(areas.sum()), 1e-12))
        native = min(abs(src.res[0]), abs(src.res[1]))
        step = typical_side * scale / SAMPLES_PER_SIDE
        extent_area = (maxx - minx) * (maxy - miny)
        step = max(step, math.sqrt(extent_area / max_samples))
        width = max(1, math.ceil((maxx - minx) / step))
        height = max(1, math.ceil((maxy - miny) / step))
        grid = from_origin(minx, maxy, step, step)
        window = from_bounds(minx, maxy - height * step, minx + width * step, maxy, src.transform)
        resampling = Resampling.nearest if step <= native else Resampling.average
        ndvi = _ndvi(src, kind, bands, window, (height, width), resampling)
    labels = rasterize(
        zip(_shapes(polys), range(1, n + 1), strict=True),
        out_shape=(height, width),
        transform=grid,
        fill=0,
        dtype="int32",
        all_touched=False,
    ).ravel()
    flat = ndvi.ravel()
    valid = ~np.isnan(flat)
    total = np.bincount(labels, minlength=n + 1)[1:].astype(float)
    nvalid = np.bincount(labels[valid], minlength=n + 1)[1:].astype(float)
    sums = np.bincount(labels[valid], weights=flat[valid], minlength=n + 1)[1:]
    with np.errstate(divide="ignore", invalid="ignore"):
        mean = np.where(nvalid > 0, sums / nvalid, np.nan)
        share = np.where(total > 0, nvalid / total, 0.0)
    # Cells narrower than a sample (slivers at the boundary): the sample under their
    # representative point.
    tiny = np.flatnonzero(total == 0)
    if len(tiny):
        pts = shapely.point_on_surface(polys[tiny])
        px = shapely.get_x(pts)
        py = shapely.get_y(pts)
        col = np.floor((px - minx) / step).astype(int)
        row = np.floor((maxy - py) / step).astype(int)
        inside = (col >= 0) & (col < width) & (row >= 0) & (row < height)
        v = np.full(len(tiny), np.nan, dtype=float)
        v[inside] = ndvi[row[inside], col[inside]]
        mean[tiny] = v
        share[tiny] = np.where(np.isnan(v), 0.0, 1.0)
    mean = np.where(share >= min_valid_share, mean, np.nan)
    info = {
        "method": "imagery_cell_mean",
        "sample_step": float(step),
        "samples": int(width * height),
        "min_valid_share": float(min_valid_share),
        "cells_without_data": int(np.isnan(mean).sum()),
        "mean_valid_share": float(share.mean()),
    }
    return CellStats(mean.astype(float), share.astype(float), info)
