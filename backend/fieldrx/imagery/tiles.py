"""Web-mercator PNG tiles from a stored COG (rio-tiler does the reading and warping).

Orthophotos render their RGB bands as they are; NDVI (stored, or computed from the red and
NIR bands of a multispectral image) renders through a red-yellow-green colour ramp over
NDVI 0..1, nodata and non-finite values transparent.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from rio_tiler.colormap import cmap
from rio_tiler.errors import TileOutsideBounds
from rio_tiler.io import Reader

TILESIZE = 256
NDVI_RANGE = (0.0, 1.0)
NDVI_COLORMAP = "rdylgn"
# zlib level 1: photo tiles barely compress further at level 6 but take ~4x longer to encode
# (bench/imagery.py measures the difference).
PNG_OPTIONS = {"ZLEVEL": 1}


def ndvi_expression(bands: dict[str, int]) -> str:
    """rio-tiler band math for NDVI = (NIR - red) / (NIR + red)."""
    return f"(b{bands['nir']}-b{bands['red']})/(b{bands['nir']}+b{bands['red']})"


def render_tile(
    path: Path, kind: str, bands: dict[str, Any], z: int, x: int, y: int
) -> bytes | None:
    """PNG bytes of tile z/x/y, or None when the raster does not reach the tile.

    rio-tiler is imported with this module, never lazily inside a request: the endpoint
    runs in a thread pool, and concurrent first imports of rio_tiler race into a
    circular-import error (500s on a map's first tiles).
    """
    with Reader(str(path)) as src:
        if not src.tile_exists(x, y, z):
            return None
        try:
            if kind == "orthophoto":
                img = src.tile(
                    x, y, z, tilesize=TILESIZE, indexes=(bands["r"], bands["g"], bands["b"])
                )
                return img.render(img_format="PNG", **PNG_OPTIONS)
            if kind == "ndvi":
                img = src.tile(x, y, z, tilesize=TILESIZE, indexes=bands["ndvi"])
            else:
                img = src.tile(x, y, z, tilesize=TILESIZE, expression=ndvi_expression(bands))
        except TileOutsideBounds:
            return None
    data = img.array.astype("float32")
    bad = ~np.isfinite(data.filled(np.nan) if np.ma.isMaskedArray(data) else data)
    img.array = np.ma.masked_array(
        np.nan_to_num(np.asarray(data), nan=0.0), mask=np.ma.getmaskarray(data) | bad
    )
    img = img.rescale(in_range=(NDVI_RANGE,))
    return img.render(img_format="PNG", colormap=cmap.get(NDVI_COLORMAP), **PNG_OPTIONS)
