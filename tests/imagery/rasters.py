"""Synthetic GeoTIFFs for the imagery tests, written with rasterio (no hand-made TIFF bytes)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rasterio
from pyproj import Transformer
from rasterio.transform import from_bounds

# A 200 m x 100 m field in UTM 49N (EPSG:32649), near seed 001's site.
UTM = 32649
X0, Y0 = 200_000.0, 3_560_000.0
FIELD_UTM = [(X0, Y0), (X0 + 200, Y0), (X0 + 200, Y0 + 100), (X0, Y0 + 100)]


def field_geojson(dx: float = 0.0) -> dict:
    tr = Transformer.from_crs(UTM, 4326, always_xy=True)
    ring = [list(tr.transform(x + dx, y)) for x, y in FIELD_UTM]
    return {"type": "Polygon", "coordinates": [ring + [ring[0]]]}


def ndvi_pattern(h: int, w: int) -> np.ndarray:
    """NDVI rising west -> east from 0.2 to 0.8."""
    return np.tile(np.linspace(0.2, 0.8, w, dtype="float32"), (h, 1))


def write_tiff(
    path: Path,
    kind: str = "orthophoto",
    *,
    crs: str | int | None = UTM,
    bounds: tuple[float, float, float, float] = (X0 - 10, Y0 - 10, X0 + 210, Y0 + 110),
    res: float = 0.5,
    count: int | None = None,
    skip_write: bool = False,
    tags: dict[str, str] | None = None,
    **profile: object,
) -> Path:
    """A tiled GeoTIFF covering ``bounds`` (in ``crs``) at ``res`` units per pixel;
    ``crs`` None: not georeferenced (no CRS, no transform)."""
    w = int(round((bounds[2] - bounds[0]) / res))
    h = int(round((bounds[3] - bounds[1]) / res))
    n = count or {"orthophoto": 3, "ndvi": 1, "multispectral": 4}[kind]
    dtype = "float32" if kind == "ndvi" else ("uint16" if kind == "multispectral" else "uint8")
    meta: dict = {
        "driver": "GTiff",
        "width": w,
        "height": h,
        "count": n,
        "dtype": dtype,
        "tiled": True,
        "blockxsize": 256,
        "blockysize": 256,
        "compress": "deflate",
    }
    if crs is not None:
        meta.update(crs=rasterio.crs.CRS.from_user_input(crs), transform=from_bounds(*bounds, w, h))
    meta.update(profile)
    if skip_write:  # sparse: a header and no pixel data at all
        with rasterio.open(path, "w", SPARSE_OK=True, **meta):
            pass
        return path
    nd = ndvi_pattern(h, w)
    with rasterio.open(path, "w", **meta) as dst:
        if tags:
            dst.update_tags(**tags)
        if kind == "orthophoto":
            g = (nd * 255).astype("uint8")
            for b in range(1, n + 1):
                dst.write(g if b == 2 else (255 - g), b)
        elif kind == "ndvi":
            dst.write(nd.astype(dtype), 1)
        else:  # red = 1000 * (1 - ndvi), nir = 1000 * (1 + ndvi): NDVI = ndvi
            for b in range(1, n + 1):
                dst.write(np.full((h, w), 500, dtype), b)
            dst.write((1000 * (1 - nd)).astype(dtype), 3)
            dst.write((1000 * (1 + nd)).astype(dtype), 4)
    return path
