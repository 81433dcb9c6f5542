"""Plan vector tiles: real ST_AsMVT bytes decoded, layer "cells", detail vs overview, auth."""

from __future__ import annotations

from tests.support.mvt import decode, lonlat_to_tile
from tests.support.plans import API, make_field, make_plan, rectangle

MVT = "application/vnd.mapbox-vector-tile"


def test_plan_tile_detail_and_overview(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h, rectangle(112.3401, 32.1401, 300, 200))
    plan = make_plan(client, h, fid)
    n = plan["n_cells"]
    lon, lat = 112.3401 + 0.0015, 32.1401 + 0.0009  # field centre
    # z19: detail, one feature per cell with seq and swath
    x, y = lonlat_to_tile(lon, lat, 19)
    r = client.get(f"{API}/tiles/plans/{plan['id']}/19/{x}/{y}.mvt", headers=h)
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == MVT
    assert r.headers["etag"] and "max-age" in r.headers["cache-control"]
    layer = decode(r.content)["cells"]
    assert layer["extent"] == 4096 and layer["version"] == 2
    feats = layer["features"]
    assert 0 < len(feats) < n
    assert all(f["type"] == 3 for f in feats)  # polygons
    assert set(feats[0]["properties"]) == {"seq", "swath"}
    seqs = [f["properties"]["seq"] for f in feats]
    assert len(set(seqs)) == len(seqs) and max(seqs) < n
    # z13: the whole field in one tile, cells binned: far fewer features than cells
    x, y = lonlat_to_tile(lon, lat, 13)
    r = client.get(f"{API}/tiles/plans/{plan['id']}/13/{x}/{y}.mvt", headers=h)
    ov = decode(r.content)["cells"]["features"]
    assert 0 < len(ov) < n / 4
    assert 0.5 * n < sum(f["properties"]["n_cells"] for f in ov) < 1.5 * n  # sampled, scaled
    assert len(r.content) < 64_000
    assert r.headers.get("content-encoding") == "gzip"  # TestClient sends Accept-Encoding: gzip
    raw = client.get(
        f"{API}/tiles/plans/{plan['id']}/13/{x}/{y}.mvt",
        headers={**h, "Accept-Encoding": "identity"},
    )
    assert "content-encoding" not in raw.headers and raw.content == r.content
    # ETag revalidation
    r2 = client.get(
        f"{API}/tiles/plans/{plan['id']}/13/{x}/{y}.mvt",
        headers={**h, "If-None-Match": r.headers["etag"]},
    )
    assert r2.status_code == 304
    # a tile far away is empty
    r = client.get(f"{API}/tiles/plans/{plan['id']}/19/0/0.mvt", headers=h)
    assert r.status_code == 200 and r.content == b""


def test_plan_tile_errors_and_tenancy(client, make_org) -> None:
    a, b = make_org(), make_org()
    plan = make_plan(client, a.headers(), make_field(client, a.headers()))
    url = f"{API}/tiles/plans/{plan['id']}/10/5/5.mvt"
    assert client.get(url, headers=a.headers("viewer")).status_code == 200
    assert client.get(url, headers=b.headers()).status_code == 404
    assert client.get(url).status_code == 401
    assert (
        client.get(f"{API}/tiles/plans/{plan['id']}/3/9/0.mvt", headers=a.headers()).status_code
        == 422
    )
    assert client.get(f"{API}/tiles/plans/999999/3/0/0.mvt", headers=a.headers()).status_code == 404
