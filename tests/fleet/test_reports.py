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


def approx(v: float, **kw: float) -> object:
    """Record times near 1.79e9 s carry ~2e-7 s of float rounding: compare to 1e-5."""
    return pytest.approx(v, **({"rel": 1e-5} | kw))


def _tile_xy(lon: float, lat: float, z: int) -> tuple[int, int]:
    n = 1 << z
    x = int((lon + 180.0) / 360.0 * n)
    y = int((1.0 - math.asinh(math.tan(math.radians(lat))) / math.pi) / 2.0 * n)
    return x, y


OUTSIDE = {"lon": 112.31990, "lat": 32.12990}  # south-west of the plot


def flow_g_s(rpm: float) -> float:
    """Seed 001 linear calibration (eq. 1): 237.2 r - 404.4 g/min."""
    return max(0.0, 237.2 * rpm - 404.4) / 60.0


@pytest.fixture()
def driven(client, org):  # noqa: ANN001, ANN201
    # no lag, so every record's mass lands where the record is (the next record's place
    # at +dt/2 is the same cell centre inside a run; runs are separated by pauses)
    fx = make_job(org.id, state="running", lag_s=0.0)
    recs = [record(fx, s, t=T0 + s * 0.1, cell=0) for s in range(1, 31)]
    recs += [
        record(fx, s, t=T0 + 13 + s * 0.1, cell=1, applied_rate_kg_ha=275.0, actual_shaft_rpm=33.0)
        for s in range(31, 61)
    ]
    recs += [record(fx, s, t=T0 + 26 + s * 0.1, cell=None, **OUTSIDE) for s in range(61, 66)]
    recs += [  # implement raised, shaft stopped: nothing metered
        record(fx, s, t=T0 + 39 + s * 0.1, cell=2, implement_down=False, actual_shaft_rpm=0.0)
        for s in range(66, 86)
    ]
    r = client.post("/api/v1/telemetry", json={"records": recs}, headers=fx.device_headers)
    assert r.json()["acked_seq"] == 85
    return fx


def test_report_matches_hand_computed_cells(client, org, driven) -> None:  # noqa: ANN001
    rep = client.get(f"/api/v1/jobs/{driven.job_id}/report", headers=org.headers("viewer")).json()
    m1 = [rate * 3.0 * 5.0 / 10.0 for rate in RATES]  # eq. 17: M * width * driven length / 10 g
    # each run's last record is followed by a pause (> 2 s): its fix period counts 0
    m2_0 = 29 * flow_g_s(30.0) * 0.1
    m2_1 = 29 * flow_g_s(33.0) * 0.1
    outside = 4 * flow_g_s(30.0) * 0.1
    cells = {c["seq"]: c for c in rep["cells"]}
    assert cells[0]["m1_g"] == approx(m1[0])
    assert cells[0]["m2_g"] == approx(m2_0)
    acc0 = (1 - abs(m1[0] - m2_0) / m1[0]) * 100  # eq. 18
    acc1 = (1 - abs(m1[1] - m2_1) / m1[1]) * 100
    assert cells[0]["accuracy_pct"] == approx(acc0)
    assert cells[1]["accuracy_pct"] == approx(acc1)
    assert cells[1]["mean_applied_rate_kg_ha"] == approx(275.0)
    assert cells[1]["applied_rate_kg_ha"] == approx(m2_1 * 10 / 15.0)
    assert cells[2]["m2_g"] == 0 and cells[2]["accuracy_pct"] == approx(0.0)
    assert cells[2]["n_records"] == 0 and cells[0]["n_records"] == 30
    assert rep["cells_planned"] == 8 and rep["cells_applied"] == 2
    assert rep["coverage_pct"] == approx(25.0)
    assert rep["planned_total_kg"] == approx(sum(m1) / 1000)
    assert rep["applied_total_kg"] == approx((m2_0 + m2_1 + outside) / 1000)
    assert rep["applied_outside_cells_kg"] == approx(outside / 1000)
    assert rep["mean_accuracy_pct"] == approx((acc0 + acc1) / 2)
    assert rep["min_accuracy_pct"] == approx(min(acc0, acc1))
    assert rep["time_worked_s"] == approx(6.2)
    summary = client.get(f"/api/v1/jobs/{driven.job_id}/summary", headers=org.headers()).json()
    assert summary["applied_total_kg"] == approx(rep["applied_total_kg"])
    assert summary["area_applied_ha"] == approx(30.0 / 1e4)


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
    f0_acc = f0["properties"]["accuracy_pct"]
    assert f0_acc == approx((1 - abs(450 - 29 * flow_g_s(30.0) * 0.1) / 450) * 100)
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
    assert len(rows) == 8 and float(rows[0]["accuracy_pct"]) == approx(f0_acc, abs=1e-5)
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
    assert len(recs) == 8 and recs[0]["ACCURACY"] == approx(f0_acc, abs=1e-3)
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


def test_job_tiles_show_the_reports_accuracy_for_every_cell(client, org, driven) -> None:  # noqa: ANN001
    """The map colours each cell by the accuracy the report (side panel) shows."""
    from tests.support.mvt import decode

    h = org.headers("viewer")
    rep = client.get(f"/api/v1/jobs/{driven.job_id}/report", headers=h).json()
    z = 18
    tiles = {_tile_xy(c["lon"], c["lat"], z) for c in driven.cells}
    shown: dict[int, dict] = {}
    for x, y in tiles:
        r = client.get(f"/api/v1/tiles/jobs/{driven.job_id}/{z}/{x}/{y}.mvt", headers=h)
        assert r.status_code == 200
        for f in decode(r.content)["cells"]["features"]:
            shown[int(f["properties"]["seq"])] = f["properties"]
    assert len(shown) == len(rep["cells"]) == 8
    for cell in rep["cells"]:
        props = shown[cell["seq"]]
        assert props.get("accuracy") == cell["accuracy_pct"] or props.get("accuracy") == approx(
            cell["accuracy_pct"]
        ), (cell["seq"], props, cell)
        assert props["applied_rate"] == approx(cell["applied_rate_kg_ha"])
        assert props["n_records"] == cell["n_records"]
    # more telemetry: the tile follows the report (the cache notices the new records)
    more = [record(driven, s, t=T0 + 60 + s * 0.1, cell=3) for s in range(86, 96)]
    r = client.post("/api/v1/telemetry", json={"records": more}, headers=driven.device_headers)
    assert r.json()["acked_seq"] == 95
    rep2 = client.get(f"/api/v1/jobs/{driven.job_id}/report", headers=h).json()
    c3 = next(c for c in rep2["cells"] if c["seq"] == 3)
    assert c3["m2_g"] > 0
    x, y = _tile_xy(driven.cells[3]["lon"], driven.cells[3]["lat"], z)
    r = client.get(f"/api/v1/tiles/jobs/{driven.job_id}/{z}/{x}/{y}.mvt", headers=h)
    f3 = next(f for f in decode(r.content)["cells"]["features"] if f["properties"]["seq"] == 3)
    assert f3["properties"]["accuracy"] == approx(c3["accuracy_pct"])


def test_report_shows_where_and_how_long_the_operator_overrode(client, org) -> None:  # noqa: ANN001
    """The cab tags each record written under an override; the report sums their fix
    periods per action, says where the first and last were, and lists each alarm
    acknowledgement with the alarms it acknowledged (not the operator's own tags)."""
    fx = make_job(org.id, state="running")
    recs = [record(fx, s, t=T0 + s * 0.1, cell=0, fix_period_s=0.1) for s in range(1, 11)]
    recs += [
        record(fx, s, t=T0 + s * 0.1, cell=1, fix_period_s=0.1,
               alarms=["operator_rate_override"], applied_rate_kg_ha=300.0)
        for s in range(11, 31)
    ]  # fmt: skip
    recs += [
        record(fx, s, t=T0 + s * 0.1, cell=2, fix_period_s=0.1, alarms=["operator_pause"])
        for s in range(31, 36)
    ]
    recs.append(
        record(fx, 36, t=T0 + 3.6, cell=2, fix_period_s=0.1,
               alarms=["alarm_ack", "operator_pause", "uplink_backlog_high"])
    )  # fmt: skip
    r = client.post("/api/v1/telemetry", json={"records": recs}, headers=fx.device_headers)
    assert r.json()["acked_seq"] == 36
    rep = client.get(f"/api/v1/jobs/{fx.job_id}/report", headers=org.headers("viewer")).json()
    over = {o["action"]: o for o in rep["operator"]["overrides"]}
    assert set(over) == {"operator_rate_override", "operator_pause"}
    assert over["operator_rate_override"]["records"] == 20
    assert over["operator_rate_override"]["seconds"] == approx(2.0)
    assert over["operator_pause"]["seconds"] == approx(0.6)
    c1, c2 = fx.cells[1], fx.cells[2]
    assert over["operator_rate_override"]["from_lon_lat"] == approx([c1["lon"], c1["lat"]])
    assert over["operator_pause"]["to_lon_lat"] == approx([c2["lon"], c2["lat"]])
    acks = rep["operator"]["alarm_acks"]
    assert len(acks) == 1 and acks[0]["alarms"] == ["uplink_backlog_high"]
    assert acks[0]["at"].startswith("2026-")
