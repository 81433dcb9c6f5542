"""Soil-sample import: per-row errors, reject rule, projected input, outside samples."""

import json

import numpy as np
import pytest
import shapely
from fieldrx.agronomy.soil import (
    SoilFormatError,
    parse_soil_csv,
    parse_soil_geojson,
    read_soil_samples,
)
from fieldrx.geo.crs import transform_xy

FIELD = shapely.box(112.3230, 32.1340, 112.3250, 32.1355)

GOOD = """sample_id,lon,lat,depth_cm,n_mg_kg,p_mg_kg,k_mg_kg,om_g_kg,ph
S1,112.3235,32.1345,20,95.5,12,110,18.2,6.1
S2,112.3240,32.1350,20,120,,,,
S3,112.3245,32.1352,20,80,10,90,15,5.8
"""


def test_good_csv():
    res = parse_soil_csv(GOOD.encode(), boundary_wgs84=FIELD)
    assert res.ok and not res.rejected and res.outside == []
    assert [s.sample_id for s in res.samples] == ["S1", "S2", "S3"]
    assert [s.row for s in res.samples] == [2, 3, 4]  # header is row 1
    s1 = res.samples[0]
    assert (s1.lon, s1.lat, s1.n_mg_kg, s1.p_mg_kg, s1.ph) == (112.3235, 32.1345, 95.5, 12.0, 6.1)
    assert res.samples[1].p_mg_kg is None


def test_errors_name_row_and_column_and_reject_everything():
    bad = (
        GOOD
        + "S4,112.3236,abc,20,90,,,,\n"
        + "S5,112.3237,32.1346,20,,,,,9.5\n"
        + "S6,112.3237,32.1346,20,70,,,,15\n"
    )
    res = parse_soil_csv(bad)
    assert res.rejected and res.samples == []
    got = [(e.row, e.column) for e in res.errors]
    assert got == [(5, "lat"), (6, "n_mg_kg"), (7, "ph")]
    assert str(res.errors[0]) == "row 5, column 'lat': expected a number, got 'abc'"
    assert "out of range" in res.errors[2].message


def test_skip_bad_rows_keeps_good_ones():
    bad = GOOD + "S4,112.3236,abc,20,90,,,,\n"
    res = parse_soil_csv(bad, skip_bad_rows=True)
    assert not res.rejected and len(res.samples) == 3
    assert [(e.row, e.column) for e in res.errors] == [(5, "lat")]


def test_all_rows_bad_or_empty_file_is_rejected_even_with_skip():
    res = parse_soil_csv("id,lon,lat,n\nA,1,x,3\n", skip_bad_rows=True)
    assert res.rejected and res.samples == [] and res.errors[0].row == 2
    empty = parse_soil_csv("id,lon,lat,n\n")
    assert empty.rejected and empty.errors[0].message == "no samples in the file"


def test_missing_column_is_fatal_even_with_skip():
    res = parse_soil_csv("id,lon,lat\nA,1,2\n", skip_bad_rows=True)
    assert res.rejected and [(e.row, e.column) for e in res.errors] == [(1, "n_mg_kg")]


def test_duplicate_ids_and_semicolons_and_aliases():
    text = "ID;Longitude;Latitude;N\nA;112.3235;32.1345;100\nA;112.3236;32.1346;90\n"
    res = parse_soil_csv(text)
    assert res.rejected
    assert (res.errors[0].row, res.errors[0].column) == (3, "sample_id")
    assert "first at row 2" in res.errors[0].message


def test_projected_xy_with_epsg():
    x, y = transform_xy([112.3235, 112.3240], [32.1345, 32.1350], 4326, 32649)
    text = f"sample_id,x,y,n_mg_kg\nA,{x[0]:.3f},{y[0]:.3f},100\nB,{x[1]:.3f},{y[1]:.3f},110\n"
    res = parse_soil_csv(text, epsg=32649, boundary_wgs84=FIELD)
    assert res.ok and res.outside == []
    assert res.samples[0].lon == pytest.approx(112.3235, abs=1e-7)
    assert res.samples[1].lat == pytest.approx(32.1350, abs=1e-7)
    # without an EPSG code x/y are not coordinates we can place
    res2 = parse_soil_csv(text)
    assert res2.rejected and "pass the EPSG code" in res2.errors[0].message
    with pytest.raises(SoilFormatError, match="EPSG"):
        parse_soil_csv(text, epsg=999999)


def test_samples_outside_field_are_reported():
    text = GOOD + "FAR,112.40,32.20,20,100,,,,\n"
    res = parse_soil_csv(text, boundary_wgs84=FIELD)
    assert res.ok and len(res.samples) == 4
    assert [s.sample_id for s in res.outside] == ["FAR"]
    (far,) = res.summary()["outside"]
    assert (far["row"], far["sample_id"]) == (5, "FAR")
    assert 9000 < far["distance_m"] < 11000  # ~0.07 deg away, measured in metres
    assert [s.sample_id for s in res.inside_samples()] == [s.sample_id for s in res.samples[:3]]


def test_geojson_samples_and_feature_errors():
    fc = {
        "type": "FeatureCollection",
        "features": [
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [112.3235, 32.1345]},
                "properties": {"sample_id": "G1", "n_mg_kg": 100, "depth_cm": 20},
            },
            {
                "type": "Feature",
                "geometry": {"type": "LineString", "coordinates": [[0, 0], [1, 1]]},
                "properties": {"n_mg_kg": 100},
            },
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [112.3236, 32.1346]},
                "properties": {"sample_id": "G3", "n_mg_kg": "lots"},
            },
        ],
    }
    res = parse_soil_geojson(json.dumps(fc).encode())
    assert res.rejected
    assert [(e.row, e.column, e.kind) for e in res.errors] == [
        (1, "geometry", "feature"),
        (2, "n_mg_kg", "feature"),
    ]
    assert str(res.errors[0]).startswith("feature 1, column 'geometry'")
    ok = read_soil_samples(
        "s.geojson",
        json.dumps({"type": "FeatureCollection", "features": fc["features"][:1]}).encode(),
    )
    assert ok.ok and ok.samples[0].sample_id == "G1" and ok.samples[0].lon == 112.3235
    with pytest.raises(SoilFormatError):
        read_soil_samples("s.xlsx", b"")


def test_ndvi_points_use_the_same_parser():
    text = "id,lon,lat,ndvi\nP1,112.3235,32.1345,0.41\nP2,112.3236,32.1346,1.7\n"
    res = parse_soil_csv(text, value_column="ndvi")
    assert res.rejected and [(e.row, e.column) for e in res.errors] == [(3, "ndvi")]
    ok = parse_soil_csv(text.splitlines(True)[0] + text.splitlines(True)[1], value_column="ndvi")
    assert ok.ok and ok.samples[0].ndvi == 0.41 and ok.samples[0].n_mg_kg is None
    assert ok.values("ndvi").tolist() == [0.41]
    missing = parse_soil_csv("id,lon,lat,n\nA,1,2,3\n", value_column="ndvi")
    assert [(e.row, e.column) for e in missing.errors] == [(1, "ndvi")]


def test_samples_just_outside_the_boundary_are_the_fields_own():
    """A sample a few metres outside (GNSS error) is within OUTSIDE_TOLERANCE_M; 30 m is not."""
    from fieldrx.agronomy.soil import OUTSIDE_TOLERANCE_M, distance_outside_m

    minx, miny, maxx, maxy = FIELD.bounds
    lat = (miny + maxy) / 2
    m_per_deg_lon = 111320 * np.cos(np.radians(lat))
    near = maxx + 3.0 / m_per_deg_lon
    far = maxx + 30.0 / m_per_deg_lon
    d = distance_outside_m(FIELD, np.array([[near, lat], [far, lat], [(minx + maxx) / 2, lat]]))
    assert d[0] == pytest.approx(3.0, abs=0.3) and d[1] == pytest.approx(30.0, abs=1.0)
    assert d[2] == 0.0
    text = (
        "sample_id,lon,lat,n_mg_kg\n"
        f"IN,{(minx + maxx) / 2},{lat},80\nNEAR,{near},{lat},80\nFAR,{far},{lat},80\n"
    )
    res = parse_soil_csv(text, boundary_wgs84=FIELD)
    assert OUTSIDE_TOLERANCE_M < 30
    assert [s.sample_id for s in res.outside] == ["FAR"]
    assert [s.sample_id for s in res.inside_samples()] == ["IN", "NEAR"]
