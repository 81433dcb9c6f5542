"""As-applied report of a job against figures computed by hand (seed 001 eq. 17-18)."""

from __future__ import annotations

import csv
import io
import math
import zipfile

import pytest
import shapefile

from tests.fleet.helpers import RATES, make_job, record

T0 = 1_790_000_000.0


def _tile_xy(lon: float, lat: float, z: int) -> tuple[int, int]:
    n = 1 << z
    x = int((lon + 180.0) / 360.0 * n)
    y = int((1.0 - math.asinh(math.tan(math.radians(lat))) / math.pi) / 2.0 * n)
    return x, y


@pytest.fixture()
def driven(client, org):  # noqa: ANN001, ANN201
    fx = make_job(org.id, state="running")
    recs = [record(fx, s, t=T0 + s * 0.1, cell=0) for s in range(1, 31)]  # on target
    recs += [  # 10 % over, after a 10 s pause
        record(fx, s, t=T0 + 13 + s * 0.1, cell=1, applied_rate_kg_ha=275.0) for s in range(31, 61)
    ]
    recs += [record(fx, s, t=T0 + 13 + s * 0.1, cell=None) for s in range(61, 66)]  # no cell
    recs += [  # implement raised: nothing metered
        record(fx, s, t=T0 + 13 + s * 0.1, cell=2, implement_down=False) for s in range(66, 86)
    ]
    r = client.post("/api/v1/telemetry", json={"records": recs}, headers=fx.device_headers)
    assert r.json()["acked_seq"] == 85
    return fx


def test_report_matches_hand_computed_cells(client, org, driven) -> None:  # noqa: ANN001
    rep = client.get(f"/api/v1/jobs/{driven.job_id}/report", headers=org.headers("viewer")).json()
    per_record = lambda rate: rate * 3.0 * 1.5 * 0.1 / 10.0  # noqa: E731  g: rate*width*v*dt/10
    m1 = [rate * 15.0 / 10.0 for rate in RATES]  # eq. 17: M*area/10 g, area 5 m x 3 m
    m2_0 = 29 * per_record(300.0)  # the 30th record is followed by a 10 s gap: dt 0
    m2_1 = 30 * per_record(275.0)
    outside = 5 * per_record(300.0)
    cells = {c["seq"]: c for c in rep["cells"]}
    assert cells[0]["m1_g"] == pytest.approx(m1[0])
    assert cells[0]["m2_g"] == pytest.approx(m2_0)
    assert cells[0]["accuracy_pct"] == pytest.approx((1 - abs(m1[0] - m2_0) / m1[0]) * 100)
    assert cells[0]["accuracy_pct"] == pytest.approx(87.0)
    assert cells[1]["accuracy_pct"] == pytest.approx(99.0)
    assert cells[1]["mean_applied_rate_kg_ha"] == pytest.approx(275.0)
    assert cells[1]["applied_rate_kg_ha"] == pytest.approx(m2_1 * 10 / 15.0)
    assert cells[2]["m2_g"] == 0 and cells[2]["accuracy_pct"] == pytest.approx(0.0)
    assert cells[2]["n_records"] == 0 and cells[0]["n_records"] == 30
    assert rep["cells_planned"] == 8 and rep["cells_applied"] == 2
    assert rep["coverage_pct"] == pytest.approx(25.0)
    assert rep["planned_total_kg"] == pytest.approx(sum(m1) / 1000)
    assert rep["applied_total_kg"] == pytest.approx((m2_0 + m2_1 + outside) / 1000)
    assert rep["applied_outside_cells_kg"] == pytest.approx(outside / 1000)
    assert rep["mean_accuracy_pct"] == pytest.approx(93.0)
    assert rep["min_accuracy_pct"] == pytest.approx(87.0)
    assert rep["time_worked_s"] == pytest.approx(6.4)
    summary = client.get(f"/api/v1/jobs/{driven.job_id}/summary", headers=org.headers()).json()
    assert summary["applied_total_kg"] == pytest.approx(rep["applied_total_kg"])
    assert summary["area_applied_ha"] == pytest.approx(30.0 / 1e4)


def test_as_applied_geojson_tiles_and_exports(client, org, make_org, driven) -> None:  # noqa: ANN001
    base = f"/api/v1/jobs/{driven.job_id}"
    h = org.headers("viewer")
    pts = client.get(f"{base}/as-applied?limit=50&offset=50", headers=h).json()
    assert pts["total"] == 85 and len(pts["features"]) == 35 and pts["next_offset"] is None
    assert pts["features"][0]["properties"]["seq"] == 51
    cells = client.get(f"{base}/as-applied/cells", headers=h).json()
    assert len(cells["features"]) == 8
    f0 = next(f for f in cells["features"] if f["id"] == 0)
    assert f0["geometry"]["type"] == "Polygon"
    assert f0["properties"]["accuracy_pct"] == pytest.approx(87.0)
    # vector tile around the plot
    z = 19
    x, y = _tile_xy(driven.cells[0]["lon"], driven.cells[0]["lat"], z)
    r = client.get(f"/api/v1/tiles/jobs/{driven.job_id}/{z}/{x}/{y}.mvt", headers=h)
    assert r.status_code == 200 and r.headers["content-type"].startswith("application/vnd.mapbox")
    assert b"cells" in r.content and b"applied_rate" in r.content and b"accuracy" in r.content
    far = client.get(f"/api/v1/tiles/jobs/{driven.job_id}/{z}/0/0.mvt", headers=h)
    assert far.status_code == 200 and far.content == b""
    # CSV
    text = client.get(f"{base}/export?format=csv", headers=h).text
    rows = list(csv.DictReader(io.StringIO(text)))
    assert len(rows) == 8 and float(rows[0]["accuracy_pct"]) == pytest.approx(87.0)
    # zipped Shapefile, read back
    z_ = zipfile.ZipFile(
        io.BytesIO(client.get(f"{base}/export?format=shapefile", headers=h).content)
    )
    stem = f"job{driven.job_id}_as_applied"
    assert {f"{stem}.{e}" for e in ("shp", "shx", "dbf", "prj")} <= set(z_.namelist())
    rd = shapefile.Reader(
        shp=io.BytesIO(z_.read(f"{stem}.shp")),
        shx=io.BytesIO(z_.read(f"{stem}.shx")),
        dbf=io.BytesIO(z_.read(f"{stem}.dbf")),
    )
    recs = {r["SEQ"]: r for r in rd.records()}
    assert len(recs) == 8 and recs[1]["ACCURACY"] == pytest.approx(99.0)
    assert rd.shape(0).shapeType == shapefile.POLYGON
    # another organisation sees nothing
    other = make_org()
    for path in (f"{base}/report", f"{base}/summary", f"{base}/as-applied", f"{base}/export"):
        assert client.get(path, headers=other.headers()).status_code == 404
    assert (
        client.get(
            f"/api/v1/tiles/jobs/{driven.job_id}/{z}/{x}/{y}.mvt", headers=other.headers()
        ).status_code
        == 404
    )
