"""Plans API against real PostGIS: create, summary, cells in path order, route, delete, 422s."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from shapely.geometry import shape

from tests.support import FIELD_WITH_HOLE, SMALL_PLOT
from tests.support.plans import API, make_field, make_plan, rectangle


def test_create_plan_summary_cells_route(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h)
    plan = make_plan(client, h, fid)
    assert plan["field_id"] == fid
    assert plan["n_cells"] > 0
    assert plan["params"]["swath_width_m"] == 2.3
    assert plan["metrics"]["n_swaths"] >= 10  # 23 m / 2.3 m or 37 m / 2.3 m
    assert plan["metrics"]["coverage_pct"] > 99
    again = client.get(f"{API}/plans/{plan['id']}", headers=org.headers("viewer")).json()
    assert again["n_cells"] == plan["n_cells"] and again["heading_deg"] == plan["heading_deg"]

    cells = client.get(f"{API}/plans/{plan['id']}/cells?limit=50000", headers=h).json()
    assert cells["type"] == "FeatureCollection" and cells["total"] == plan["n_cells"]
    feats = cells["features"]
    assert [f["properties"]["seq"] for f in feats] == list(range(plan["n_cells"]))
    polys = [shape(f["geometry"]) for f in feats]
    field = shape(SMALL_PLOT)
    total = sum(p.area for p in polys)
    assert total == pytest.approx(field.area, rel=0.01)
    # consecutive cells of one swath share an edge (the walk is continuous)
    for a, b in zip(feats, feats[1:], strict=False):
        if a["properties"]["swath"] == b["properties"]["swath"]:
            pa, pb = shape(a["geometry"]), shape(b["geometry"])
            assert pa.buffer(1e-7).intersection(pb).length > 0 or pa.distance(pb) < 1e-7
            assert b["properties"]["index_in_swath"] == a["properties"]["index_in_swath"] + 1
    areas = np.array([f["properties"]["area_m2"] for f in feats])
    assert areas.max() <= 2.3 * 5.0 + 1e-6

    page = client.get(f"{API}/plans/{plan['id']}/cells?limit=3&offset=5", headers=h).json()
    assert [f["properties"]["seq"] for f in page["features"]] == [5, 6, 7]

    route = client.get(f"{API}/plans/{plan['id']}/route", headers=h).json()
    assert route["type"] == "Feature" and route["geometry"]["type"] == "LineString"
    line = shape(route["geometry"])
    # drivable turns reach beyond the field by the headland they need
    reach_deg = plan["metrics"]["required_headland_m"] / 80_000.0
    assert line.buffer(1e-6).within(field.buffer(1e-5 + reach_deg))
    assert route["properties"]["n_swaths"] == plan["metrics"]["n_swaths"]

    listed = client.get(f"{API}/fields/{fid}/plans", headers=h).json()
    assert [p["id"] for p in listed["items"]] == [plan["id"]]


def test_cells_follow_route_order(client, org) -> None:
    """Cell centres, in seq order, advance along the stored route (path order)."""
    h = org.headers()
    fid = make_field(client, h, rectangle(112.33, 32.14, 60, 30))
    plan = make_plan(client, h, fid, heading="optimal", cell_length_m=4)
    feats = client.get(f"{API}/plans/{plan['id']}/cells?limit=50000", headers=h).json()["features"]
    route = shape(client.get(f"{API}/plans/{plan['id']}/route", headers=h).json()["geometry"])
    pos = [route.project(shape(f["geometry"]).centroid) for f in feats]
    assert all(b >= a - 1e-9 for a, b in zip(pos, pos[1:], strict=False))


def test_plan_with_hole_has_no_cell_in_the_hole(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h, FIELD_WITH_HOLE)
    plan = make_plan(client, h, fid, swath_width_m=12, cell_length_m=10, headland_passes=1)
    feats = client.get(f"{API}/plans/{plan['id']}/cells?limit=50000", headers=h).json()["features"]
    assert len(feats) == plan["n_cells"]
    hole = shapely.Polygon(FIELD_WITH_HOLE["coordinates"][1])
    for f in feats:
        c = shape(f["geometry"]).representative_point()
        assert not hole.contains(c)


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        ({"swath_width_m": 0}, "swath_width_m must be > 0"),
        ({"swath_width_m": -2}, "swath_width_m must be > 0"),
        ({"swath_width_m": 60}, "wider than the field in every direction"),
        ({"cell_length_m": 0.2}, "cell_length_m must be >= 0.5"),
        ({"heading": "angle"}, "needs angle_deg"),
    ],
)
def test_bad_parameters_are_422_and_store_nothing(client, org, db, body, needle) -> None:
    from sqlalchemy import text

    h = org.headers()
    fid = make_field(client, h)
    r = client.post(f"{API}/fields/{fid}/plans", headers=h, json=body)
    assert r.status_code == 422, r.text
    assert needle in r.json()["detail"]
    assert db.scalar(text("SELECT count(*) FROM plans WHERE field_id = :f"), {"f": fid}) == 0


def test_too_many_cells_is_422(client, org) -> None:
    h = org.headers()
    fid = make_field(client, h, rectangle(112.30, 32.10, 3000, 3000))
    r = client.post(
        f"{API}/fields/{fid}/plans", headers=h, json={"swath_width_m": 1.0, "cell_length_m": 0.5}
    )
    assert r.status_code == 422
    assert "more than 5000000" in r.json()["detail"]


def test_request_validation_is_422(client, org) -> None:
    fid = make_field(client, org.headers())
    r = client.post(f"{API}/fields/{fid}/plans", headers=org.headers(), json={"heading": "spiral"})
    assert r.status_code == 422


def test_delete_plan_removes_cells(client, org, db) -> None:
    from sqlalchemy import text

    h = org.headers()
    plan = make_plan(client, h, make_field(client, h))
    assert (
        client.delete(f"{API}/plans/{plan['id']}", headers=org.headers("viewer")).status_code == 403
    )
    assert client.delete(f"{API}/plans/{plan['id']}", headers=h).status_code == 204
    assert client.get(f"{API}/plans/{plan['id']}", headers=h).status_code == 404
    n = db.scalar(text("SELECT count(*) FROM plan_cells WHERE plan_id = :p"), {"p": plan["id"]})
    assert n == 0


def test_demo_size_field_stores_grid_in_path_order(client, org, db) -> None:
    """A ~10 ha field: every cell stored, seq 0..n-1, consecutive cells adjacent or a turn."""
    from sqlalchemy import text

    h = org.headers()
    fid = make_field(client, h, rectangle(112.31, 32.12, 400, 250))
    plan = make_plan(client, h, fid)
    n = plan["n_cells"]
    assert n > 8000
    row = db.execute(
        text("SELECT count(*), min(seq), max(seq), sum(area_m2) FROM plan_cells WHERE plan_id=:p"),
        {"p": plan["id"]},
    ).one()
    assert row[0] == n and row[1] == 0 and row[2] == n - 1
    assert row[3] == pytest.approx(400 * 250, rel=0.01)
    # the gap between consecutive cell centres is one cell length within a swath
    d = db.execute(
        text(
            "SELECT max(ST_Distance(a.c::geography, b.c::geography)) FROM "
            "(SELECT seq, swath, ST_Centroid(geom) c FROM plan_cells WHERE plan_id=:p) a "
            "JOIN (SELECT seq, swath, ST_Centroid(geom) c FROM plan_cells WHERE plan_id=:p) b "
            "ON b.seq = a.seq + 1 AND a.swath = b.swath"
        ),
        {"p": plan["id"]},
    ).scalar()
    assert d <= 5.0 * 1.1 + 0.01  # slivers merge into the neighbour: up to 1.1 L
    # corners_utm round-trip: 8 numbers per cell
    c = db.scalar(
        text("SELECT corners_utm FROM plan_cells WHERE plan_id=:p AND seq=0"), {"p": plan["id"]}
    )
    assert len(c) == 8


def test_partition_per_plan_follows_plan_and_field_lifecycle(client, org, db) -> None:
    """Each plan's cells live in their own partition; deleting the plan or its field drops it."""
    from sqlalchemy import text

    h = org.headers()
    fid = make_field(client, h)
    p1, p2 = make_plan(client, h, fid), make_plan(client, h, fid, heading="optimal")

    def exists(pid: int) -> bool:
        return bool(
            db.scalar(text("SELECT to_regclass(:t) IS NOT NULL"), {"t": f"plan_cells_p{pid}"})
        )

    assert exists(p1["id"]) and exists(p2["id"])
    n = db.scalar(
        text("SELECT count(*) FROM plan_cells_p" + str(p1["id"])),
    )
    assert n == p1["n_cells"]
    db.rollback()  # release our locks: dropping a partition needs an exclusive lock
    assert client.delete(f"{API}/plans/{p1['id']}", headers=h).status_code == 204
    db.rollback()
    assert not exists(p1["id"]) and exists(p2["id"])
    db.rollback()
    assert client.delete(f"{API}/fields/{fid}", headers=h).status_code == 204
    db.rollback()
    assert not exists(p2["id"])
    assert client.get(f"{API}/plans/{p2['id']}", headers=h).status_code == 404


def test_delete_while_cells_are_read_is_409_not_a_hang(client, org, db) -> None:
    from sqlalchemy import text

    h = org.headers()
    plan = make_plan(client, h, make_field(client, h))
    db.execute(text("SELECT count(*) FROM plan_cells WHERE plan_id = :p"), {"p": plan["id"]})
    r = client.delete(f"{API}/plans/{plan['id']}", headers=h)  # our open transaction holds a lock
    assert r.status_code == 409 and "in use" in r.json()["detail"]
    db.rollback()
    assert client.get(f"{API}/plans/{plan['id']}", headers=h).status_code == 200
    assert client.delete(f"{API}/plans/{plan['id']}", headers=h).status_code == 204


def test_plan_takes_the_turning_radius_and_plans_narrow_fields(client, org) -> None:
    """The API takes turn_radius_m / reverse; passes that leave no inner area
    give a headland-only plan with a warning instead of a 422."""
    h = org.headers()
    fid = make_field(client, h)
    plan = make_plan(client, h, fid, heading="optimal", turn_radius_m=4.0, reverse=True)
    m = plan["metrics"]
    assert plan["params"]["turn_radius_m"] == 4.0 and m["turn_radius_m"] == 4.0
    assert m["reverse"] is True and m["turn_kinds"].get("fishtail", 0) > 0
    assert m["required_headland_passes"] >= 1 and m["warnings"]
    r = client.post(f"{API}/fields/{fid}/plans", headers=h, json={"turn_radius_m": 0})
    assert r.status_code == 422
    skip = make_plan(client, h, fid, pattern="auto", turn_radius_m=4.0)
    assert skip["params"]["pattern"] == "auto"
    ring = make_plan(client, h, fid, headland_passes=6)
    assert any("headland-only" in w for w in ring["metrics"]["warnings"])
