"""WGS84 <-> UTM conversion: all FieldRx geometry work happens in metres (docs/architecture.md)."""

from __future__ import annotations

import math
from functools import lru_cache
from typing import TypeVar

import numpy as np
import shapely
from pyproj import Transformer
from shapely.geometry.base import BaseGeometry

G = TypeVar("G", bound=BaseGeometry)


def utm_epsg_for(lon: float, lat: float) -> int:
    """EPSG code of the WGS84 / UTM zone containing (lon, lat).

    Includes the Norway (32V) and Svalbard (31X-37X) exceptions so the zone matches
    what GIS tools pick.
    """
    if not (-180.0 <= lon <= 180.0 and -90.0 <= lat <= 90.0):
        raise ValueError(f"not a lon/lat position: ({lon}, {lat})")
    zone = int(math.floor((lon + 180.0) / 6.0)) + 1
    zone = min(max(zone, 1), 60)
    if 56.0 <= lat < 64.0 and 3.0 <= lon < 12.0:
        zone = 32
    if 72.0 <= lat < 84.0 and 0.0 <= lon < 42.0:
        if lon < 9.0:
            zone = 31
        elif lon < 21.0:
            zone = 33
        elif lon < 33.0:
            zone = 35
        else:
            zone = 37
    return (32600 if lat >= 0 else 32700) + zone


@lru_cache(maxsize=64)
def _transformer(src: int, dst: int) -> Transformer:
    return Transformer.from_crs(src, dst, always_xy=True)


# above this many points a conversion is split over two threads (pyproj frees the GIL):
# a 870k-cell grid has ~4.5 million vertices
PARALLEL_POINTS = 200_000


def transform_xy(
    x: np.ndarray, y: np.ndarray, src_epsg: int, dst_epsg: int
) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised coordinate conversion between two EPSG codes (x/lon first, always).

    The one place FieldRx calls pyproj for points; large arrays run on two threads,
    each with its own Transformer (a Transformer is not thread-safe).
    """
    x = np.ascontiguousarray(x, dtype=float)
    y = np.ascontiguousarray(y, dtype=float)
    n = x.size
    if n < PARALLEL_POINTS:
        tx, ty = _transformer(src_epsg, dst_epsg).transform(x, y)
        return np.asarray(tx, float), np.asarray(ty, float)
    from concurrent.futures import ThreadPoolExecutor

    xf, yf = x.ravel(), y.ravel()
    ox, oy = np.empty(n), np.empty(n)

    def work(sl: slice) -> None:
        tr = Transformer.from_crs(src_epsg, dst_epsg, always_xy=True)
        ox[sl], oy[sl] = tr.transform(xf[sl], yf[sl])

    with ThreadPoolExecutor(2) as ex:
        list(ex.map(work, [slice(0, n // 2), slice(n // 2, n)]))
    return ox.reshape(x.shape), oy.reshape(y.shape)


def lonlat_to_utm_xy(lon: np.ndarray, lat: np.ndarray, epsg: int) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised lon/lat -> UTM easting/northing (metres)."""
    return transform_xy(lon, lat, 4326, epsg)


def utm_xy_to_lonlat(x: np.ndarray, y: np.ndarray, epsg: int) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised UTM easting/northing -> lon/lat (degrees)."""
    return transform_xy(x, y, epsg, 4326)


def lonlat_to_utm_coords(coords: np.ndarray, epsg: int) -> np.ndarray:
    """(..., 2) lon/lat array -> same-shaped UTM array."""
    c = np.asarray(coords, float)
    x, y = lonlat_to_utm_xy(c[..., 0], c[..., 1], epsg)
    return np.stack([x, y], axis=-1)


def utm_coords_to_lonlat(coords: np.ndarray, epsg: int) -> np.ndarray:
    """(..., 2) UTM array -> same-shaped lon/lat array."""
    c = np.asarray(coords, float)
    lon, lat = utm_xy_to_lonlat(c[..., 0], c[..., 1], epsg)
    return np.stack([lon, lat], axis=-1)


def to_utm(geom_wgs84: G, epsg: int) -> G:
    """Shapely geometry (or array of them) in lon/lat -> UTM metres."""
    out: G = shapely.transform(geom_wgs84, lambda c: lonlat_to_utm_coords(c, epsg))
    return out


def to_wgs84(geom_utm: G, epsg: int) -> G:
    """Shapely geometry (or array of them) in UTM metres -> lon/lat."""
    out: G = shapely.transform(geom_utm, lambda c: utm_coords_to_lonlat(c, epsg))
    return out


# The one area basis of FieldRx: every area (a field's, a cell's, a prescription's, a job's
# applied area, the ISO 11783 partfield and TimeLog totals) is measured flat in the field's
# UTM plane, where its plan, cells and route are computed. A field's area then equals what
# its cells can cover (clipped cells never sum to more), which a geodesic field area (up to
# 0.2 % larger or smaller than the plane's at a zone edge: the UTM scale factor squared)
# would not.
AREA_BASIS = "utm"


def plane_area_m2(geom_wgs84: BaseGeometry, epsg: int) -> float:
    """Area (m^2, holes subtracted, any ring winding) of a lon/lat geometry in UTM zone
    ``epsg``: the one area basis (``AREA_BASIS``)."""
    return float(shapely.area(to_utm(geom_wgs84, epsg)))


def epsg_for_geometry(geom_wgs84: BaseGeometry) -> int:
    """UTM zone of a lon/lat geometry, chosen from its centroid."""
    c = geom_wgs84.centroid
    return utm_epsg_for(c.x, c.y)


# Coordinate systems a soil lab's file is offered in (German labs: Gauss-Krüger zone 3 from
# older ATKIS data, ETRS89/UTM 32N since the 2010s switch, GNSS lon/lat from handhelds).
WGS84 = 4326
ETRS89_UTM32N = 25832
ETRS89_UTM32N_ZONE_PREFIX = 4647  # easting written with the zone number in front (32xxxxxx)
GAUSS_KRUEGER_3 = 31467


class CrsError(ValueError):
    """An EPSG code pyproj does not know, or one that is not a 2-D coordinate system."""


@lru_cache(maxsize=128)
def crs_name(epsg: int) -> str:
    """pyproj's name of an EPSG code (``CrsError`` when it has none)."""
    from pyproj import CRS
    from pyproj.exceptions import CRSError

    try:
        return str(CRS.from_epsg(int(epsg)).name)
    except (CRSError, ValueError, TypeError) as exc:
        raise CrsError(f"unknown EPSG code {epsg!r}") from exc


def etrs89_utm_epsg_for(lon: float, lat: float) -> int:
    """ETRS89 / UTM code (258zz) of the zone at (lon, lat) in Europe (zones 28-38 north),
    else the WGS84 / UTM code: the two datums differ by < 1 m in Europe, but a lab file in
    Germany is in ETRS89 by law (AdV, since 2015) and is labelled so."""
    wgs = utm_epsg_for(lon, lat)
    zone = wgs % 100
    if wgs // 100 == 326 and 28 <= zone <= 38 and 34.0 <= lat <= 72.0:
        return 25800 + zone
    return wgs


def import_crs_choices(lon: float, lat: float) -> list[int]:
    """The coordinate systems offered for a file of points near (lon, lat), most likely first."""
    out = [WGS84, etrs89_utm_epsg_for(lon, lat), utm_epsg_for(lon, lat)]
    out += [ETRS89_UTM32N, ETRS89_UTM32N_ZONE_PREFIX, GAUSS_KRUEGER_3]
    return list(dict.fromkeys(out))


def guess_epsg(x: np.ndarray, y: np.ndarray, lon: float, lat: float) -> int | None:
    """The coordinate system a column pair's magnitudes point at, near a field at (lon, lat).

    lon/lat ranges -> WGS84; an 8-digit easting starting with a zone number (32xxxxxx) ->
    UTM with the zone prefix; 7 digits (2.5-5.9 million) -> Gauss-Krüger, zone = first
    digit (EPSG 31466-31469); 6 digits with a northing below 10,000 km -> the field's UTM
    zone (ETRS89 in Europe). None when nothing fits: the user chooses.
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y)
    if not ok.any():
        return None
    mx, my = float(np.median(x[ok])), float(np.median(y[ok]))
    if np.all(np.abs(x[ok]) <= 180) and np.all(np.abs(y[ok]) <= 90):
        return WGS84
    if 1e7 <= mx < 1e8 and 0 <= my < 1e7:
        zone = int(mx // 1e6)
        if zone == 32:
            return ETRS89_UTM32N_ZONE_PREFIX
        return None
    if 2.5e6 <= mx < 6e6 and 5.2e6 <= my < 6.2e6:
        return 31464 + int(mx // 1e6)  # zone 2 -> 31466 ... zone 5 -> 31469
    if 1e5 <= mx < 1e6 and 0 <= my < 1e7:
        return etrs89_utm_epsg_for(lon, lat)
    return None
