import numpy as np
import pytest
import shapely
from fieldrx.agronomy.cells import FLAG_BITS, CellTable
from fieldrx.geo.crs import to_wgs84

EPSG = 32649  # UTM 49N: seed 001's field near 112.32 E, 32.13 N
X0, Y0 = 624000.0, 3556000.0


def make_field_utm():
    """A trapezoid field with a pond (hole): clipped and multi-ring cells at the edges."""
    outer = shapely.Polygon([(X0, Y0), (X0 + 46, Y0), (X0 + 46, Y0 + 60), (X0, Y0 + 42)])
    pond = shapely.Point(X0 + 20, Y0 + 25).buffer(4.0, quad_segs=4)
    return outer.difference(pond)


@pytest.fixture
def field_utm():
    return make_field_utm()


@pytest.fixture
def field_wgs84():
    return to_wgs84(make_field_utm(), EPSG)


@pytest.fixture
def cells():
    """~240 clipped cells with rates 180..880 kg/ha and a few flags."""
    c = CellTable.rectangle(EPSG, X0, Y0, 20, 12, 2.3, 5.0, clip=make_field_utm())
    n = len(c)
    rates = np.round(180.0 + 700.0 * ((np.arange(n) * 37) % 101) / 100.0, 2)
    flags = np.zeros(n, dtype=np.uint16)
    flags[::17] = FLAG_BITS["no_data"]
    flags[5] |= FLAG_BITS["manual"]
    return c.with_rates(rates, flags)
