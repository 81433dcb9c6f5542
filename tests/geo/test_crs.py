import numpy as np
import pytest
from fieldrx.geo.crs import to_utm, to_wgs84, utm_epsg_for
from shapely.geometry import Polygon


@pytest.mark.parametrize(
    ("lon", "lat", "epsg"),
    [
        (11.0, 48.0, 32632),  # Bavaria
        (-70.6, -33.4, 32719),  # Santiago
        (116.4, 39.9, 32650),  # Beijing
        (5.3, 60.4, 32632),  # Bergen: Norway exception (32V)
        (15.0, 78.0, 32633),  # Svalbard exception
        (-180.0, 0.0, 32601),
        (180.0, 0.0, 32660),
    ],
)
def test_utm_zone(lon, lat, epsg):
    assert utm_epsg_for(lon, lat) == epsg


def test_round_trip_and_metres():
    ll = Polygon([(11.0, 48.0), (11.01, 48.0), (11.01, 48.01), (11.0, 48.01)])
    epsg = utm_epsg_for(11.005, 48.005)
    utm = to_utm(ll, epsg)
    # 0.01 deg of latitude is ~1113 m; of longitude at 48 N ~744 m
    c = np.asarray(utm.exterior.coords)
    south, west = np.hypot(*(c[1] - c[0])), np.hypot(*(c[3] - c[0]))
    assert 740 < south < 750 and 1105 < west < 1120
    back = to_wgs84(utm, epsg)
    assert np.allclose(np.asarray(back.exterior.coords), np.asarray(ll.exterior.coords), atol=1e-9)


def test_rejects_non_lonlat():
    with pytest.raises(ValueError):
        utm_epsg_for(500000.0, 5300000.0)
