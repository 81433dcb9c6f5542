"""Imagery: GeoTIFF -> Cloud-Optimized GeoTIFF ingest, web-mercator tiles and
per-cell raster statistics, on rasterio (bundled GDAL) and rio-tiler.

No database access here: the API layer looks rows up and passes paths and band roles in.
"""

from __future__ import annotations

KINDS = ("orthophoto", "ndvi", "multispectral")


class ImageryError(ValueError):
    """A raster that cannot be accepted or read; the message says what and where (422)."""
