import json
import subprocess
import sys
import time

import pytest

from tests.support import scaled

pytestmark = pytest.mark.slow  # each test starts the CLI in a new Python process

FIELD = {
    "type": "FeatureCollection",
    "features": [
        {
            "type": "Feature",
            "properties": {"name": "pond field"},
            "geometry": {
                "type": "Polygon",
                "coordinates": [
                    [
                        [11.0, 48.0],
                        [11.004, 48.0],
                        [11.004, 48.0025],
                        [11.0, 48.0025],
                        [11.0, 48.0],
                    ],
                    [
                        [11.0015, 48.001],
                        [11.0025, 48.001],
                        [11.0025, 48.0016],
                        [11.0015, 48.0016],
                        [11.0015, 48.001],
                    ],
                ],
            },
        }
    ],
}
KEYS = {
    "n_swaths",
    "n_turns",
    "heading_deg",
    "working_length_m",
    "nonworking_length_m",
    "coverage_pct",
    "overlap_pct",
    "outside_pct",
    "route_outside_m",
    "route_in_holes_m",
    "n_cells",
    "elapsed_s",
}


def _run(*args):
    return subprocess.run(
        [sys.executable, "-m", "fieldrx.commands.plan", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=scaled(120),
    )


def test_cli_plan_json_and_outputs(tmp_path):
    src = tmp_path / "field.geojson"
    src.write_text(json.dumps(FIELD))
    cells, route = tmp_path / "cells.geojson", tmp_path / "route.geojson"
    r = _run(
        src,
        "--swath-width",
        2.3,
        "--cell-length",
        5,
        "--heading",
        "optimal",
        "--headland-passes",
        1,
        "--turn-radius",
        1.0,
        "--out",
        cells,
        "--route-out",
        route,
        "--json",
    )
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert KEYS <= out.keys()
    assert out["n_turns"] == out["n_swaths"] - 1
    assert out["coverage_pct"] > 99.0
    assert out["route_outside_m"] == 0.0 and out["route_in_holes_m"] == 0.0
    assert 0 <= out["heading_deg"] < 180
    fc = json.loads(cells.read_text())
    assert fc["type"] == "FeatureCollection" and len(fc["features"]) == out["n_cells"]
    lon, lat = fc["features"][0]["geometry"]["coordinates"][0][0]
    assert 10.99 < lon < 11.01 and 47.99 < lat < 48.01
    rt = json.loads(route.read_text())
    assert rt["geometry"]["type"] == "LineString"


def test_cli_bare_geometry_and_fixed_angle(tmp_path):
    src = tmp_path / "geom.json"
    src.write_text(json.dumps(FIELD["features"][0]["geometry"]))
    r = _run(src, "--heading", "angle", "--angle-deg", 0, "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["heading_deg"] == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize(
    ("args", "reason"),
    [
        (["--swath-width", 0], "swath_width_m must be > 0"),
        (["--cell-length", 0.2], "cell_length_m must be >= 0.5"),
        (["--swath-width", 500], "wider than the field in every direction"),
        # the cost estimate runs before the coverage path: a 1 cm swath with 1 cm cells
        # used to plan ~30,000 swaths before the grid refused the cell length
        (["--swath-width", 0.01, "--cell-length", 0.01], "cell_length_m must be >= 0.5"),
    ],
)
def test_cli_bad_parameters(tmp_path, args, reason):
    src = tmp_path / "field.geojson"
    src.write_text(json.dumps(FIELD))
    t0 = time.monotonic()
    r = _run(src, *args, "--json")
    assert time.monotonic() - t0 < 60
    assert r.returncode == 2
    assert reason in json.loads(r.stdout)["error"]
    assert reason in r.stderr


def test_cli_rejects_projected_coordinates(tmp_path):
    src = tmp_path / "utm.geojson"
    src.write_text(
        json.dumps(
            {
                "type": "Polygon",
                "coordinates": [
                    [[500000, 5300000], [500100, 5300000], [500100, 5300100], [500000, 5300000]]
                ],
            }
        )
    )
    r = _run(src, "--json")
    assert r.returncode == 2 and "lon/lat" in r.stderr


def test_cli_validates_the_boundary_like_the_api(tmp_path):
    # the CLI never validated; a self-intersecting traced boundary ran past
    # 300 s (or was planned silently at 80-99.8 % coverage) while the API answered 422
    import time

    from fieldrx.geo.validate import BoundaryError, validate_boundary

    ring = [[11.0, 48.0], [11.004, 48.0025], [11.004, 48.0], [11.0, 48.0025], [11.0, 48.0]]
    geom = {"type": "Polygon", "coordinates": [ring]}
    with pytest.raises(BoundaryError) as api:
        validate_boundary(geom)  # what the API's field endpoints call
    src = tmp_path / "bowtie.geojson"
    src.write_text(json.dumps(geom))
    t = time.perf_counter()
    r = _run(src, "--json")
    assert time.perf_counter() - t < 30
    assert r.returncode == 2
    err = json.loads(r.stdout)["error"]
    assert api.value.message in err and "Self-intersection" in err


@pytest.mark.parametrize("radius", [5.0, 8.0])
def test_cli_route_geojson_has_no_turn_tighter_than_the_radius(tmp_path, radius):
    # The acceptance test: `fieldrx plan --turn-radius R [--reverse]`; the route GeoJSON
    # is measured back in UTM metres, vertex by vertex
    import numpy as np
    import shapely
    from fieldrx.geo.crs import to_utm

    from tests.geo.cases import min_turn_radius

    geom = {"type": "Polygon", "coordinates": [FIELD["features"][0]["geometry"]["coordinates"][0]]}
    src, route = tmp_path / "f.geojson", tmp_path / "route.geojson"
    src.write_text(json.dumps(geom))
    for extra in ([], ["--reverse"]):
        r = _run(src, "--turn-radius", radius, *extra, "--route-out", route, "--json")
        assert r.returncode == 0, r.stderr
        out = json.loads(r.stdout)
        assert out["turn_radius_m"] == radius and out["undrivable_connections"] == 0
        ll = shapely.from_geojson(json.dumps(json.loads(route.read_text())["geometry"]))
        utm = to_utm(ll, out["epsg"])
        assert min_turn_radius(np.asarray(utm.coords)) >= 0.99 * radius
        assert (out["reverse_m"] > 0) == bool(extra)
