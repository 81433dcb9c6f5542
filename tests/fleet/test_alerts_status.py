"""One test per alert kind, acknowledgement, machine status, track replay and chart data."""

from __future__ import annotations

import datetime as dt
import time

from sqlalchemy import text

from tests.fleet.helpers import make_job, record

T0 = 1_790_000_000.0


def _post(client, fx, records):  # noqa: ANN001, ANN202
    r = client.post("/api/v1/telemetry", json={"records": records}, headers=fx.device_headers)
    assert r.status_code == 200, r.text
    return r.json()


def _alerts(client, org, fx, **params):  # noqa: ANN001, ANN202
    r = client.get(
        "/api/v1/alerts", params={"machine_id": fx.machine_id, **params}, headers=org.headers()
    )
    assert r.status_code == 200, r.text
    return r.json()["items"]


def _drive(client, fx, n, start_seq=1, batch=20, **kw):  # noqa: ANN001, ANN202
    """n records at 10 Hz from T0, sent in batches (so conditions span batches)."""
    recs = [record(fx, s, t=T0 + (s - 1) * 0.1, **kw) for s in range(start_seq, start_seq + n)]
    for i in range(0, n, batch):
        _post(client, fx, recs[i : i + batch])


def test_rate_error_alert(client, org) -> None:  # noqa: ANN001
    fx = make_job(org.id, state="running")
    _drive(client, fx, 40, applied_rate_kg_ha=240.0)  # 20 % low for 4 s: below 5 s
    assert _alerts(client, org, fx) == []
    _drive(client, fx, 30, start_seq=41, applied_rate_kg_ha=240.0)  # 7 s in total
    (a,) = _alerts(client, org, fx)
    assert a["kind"] == "rate_error" and a["active"] and abs(a["value"] - 20.0) < 1e-6
    started = dt.datetime.fromisoformat(a["started_at"]).timestamp()
    assert abs(started - T0) < 1e-3  # the run began with the first off-target record
    _drive(client, fx, 5, start_seq=71)  # back on target
    (a,) = _alerts(client, org, fx)
    assert not a["active"]
    assert abs(dt.datetime.fromisoformat(a["ended_at"]).timestamp() - (T0 + 7.0)) < 1e-3


def test_speed_out_of_range_alert(client, org) -> None:  # noqa: ANN001
    fx = make_job(org.id, state="running")  # calibrated 0.8-2.5 m/s
    _drive(client, fx, 20, speed_filtered_m_s=3.4)  # 2 s: too short
    _drive(client, fx, 10, start_seq=21)
    assert _alerts(client, org, fx) == []
    _drive(client, fx, 40, start_seq=31, speed_filtered_m_s=0.3)
    (a,) = _alerts(client, org, fx, active=True)
    assert a["kind"] == "speed_out_of_range" and a["value"] == 0.3
    # raised implement: speed does not matter
    fy = make_job(org.id, state="running")
    _drive(client, fy, 40, speed_filtered_m_s=0.3, implement_down=False)
    assert _alerts(client, org, fy) == []


def test_shaft_saturation_alert(client, org) -> None:  # noqa: ANN001
    fx = make_job(org.id, state="running")
    _drive(client, fx, 30, alarms=["shaft_above_range"])
    (a,) = _alerts(client, org, fx)
    assert a["kind"] == "shaft_saturation" and a["active"]


def test_fix_lost_alert(client, org) -> None:  # noqa: ANN001
    fx = make_job(org.id, state="running")
    _drive(client, fx, 30, fix_quality=0, lon=None, lat=None)
    (a,) = _alerts(client, org, fx)
    assert a["kind"] == "fix_lost"
    _drive(client, fx, 3, start_seq=31)
    assert _alerts(client, org, fx, active=True) == []
    assert len(_alerts(client, org, fx, active=False)) == 1


def test_no_data_alert_and_status(client, db, org) -> None:  # noqa: ANN001
    fx = make_job(org.id, state="running")
    idle = make_job(org.id, state="planned")  # no running job: never no_data
    _post(client, fx, [record(fx, 1)])
    r = client.get("/api/v1/machines/status", headers=org.headers("viewer"))
    assert r.status_code == 200, r.text
    items = {m["machine_id"]: m for m in r.json()["items"]}
    m = items[fx.machine_id]
    assert m["online"] and m["job"]["id"] == fx.job_id and m["job"]["state"] == "running"
    assert m["position"]["coordinates"] == [fx.cells[0]["lon"], fx.cells[0]["lat"]]
    assert m["target_rate_kg_ha"] == 300.0 and m["rate_error_pct"] == 0.0
    assert not items[idle.machine_id]["online"] and items[idle.machine_id]["position"] is None
    assert _alerts(client, org, fx) == []
    db.execute(
        text(
            "UPDATE machine_status SET last_seen_at = now() - interval '5 minutes'"
            " WHERE machine_id = :m"
        ),
        {"m": fx.machine_id},
    )
    db.commit()
    items = {
        m["machine_id"]: m
        for m in client.get("/api/v1/machines/status", headers=org.headers()).json()["items"]
    }
    assert not items[fx.machine_id]["online"] and items[fx.machine_id]["active_alerts"] == 1
    (a,) = _alerts(client, org, fx)
    assert a["kind"] == "no_data" and a["active"]
    client.get("/api/v1/machines/status", headers=org.headers())  # idempotent
    assert len(_alerts(client, org, fx)) == 1
    assert _alerts(client, org, idle) == []
    _post(client, fx, [record(fx, 2)])  # data again: the alert ends
    assert _alerts(client, org, fx, active=True) == []


def test_ack_alert(client, make_org) -> None:  # noqa: ANN001
    org, other = make_org(), make_org()
    fx = make_job(org.id, state="running")
    _drive(client, fx, 30, alarms=["motor_saturated"])
    (a,) = _alerts(client, org, fx)
    assert (
        client.post(f"/api/v1/alerts/{a['id']}/ack", headers=org.headers("viewer")).status_code
        == 403
    )
    assert client.post(f"/api/v1/alerts/{a['id']}/ack", headers=other.headers()).status_code == 404
    assert client.get("/api/v1/alerts", headers=other.headers()).json()["total"] == 0
    r = client.post(f"/api/v1/alerts/{a['id']}/ack", headers=org.headers())
    assert r.status_code == 200
    assert r.json()["acknowledged_by"] == org.user_ids["agronomist"] and r.json()["active"]
    assert _alerts(client, org, fx, acknowledged=False) == []


def test_track_and_chart(client, make_org) -> None:  # noqa: ANN001
    org, other = make_org(), make_org()
    fx = make_job(org.id, state="running")
    _drive(client, fx, 30, batch=30)
    base = f"/api/v1/machines/{fx.machine_id}"
    page = client.get(f"{base}/track?limit=10&offset=10", headers=org.headers()).json()
    assert page["total"] == 30 and page["next_offset"] == 20
    assert [f["properties"]["seq"] for f in page["features"]] == list(range(11, 21))
    frm = dt.datetime.fromtimestamp(T0 + 1.0, dt.UTC).isoformat()
    to = dt.datetime.fromtimestamp(T0 + 1.45, dt.UTC).isoformat()
    page = client.get(f"{base}/track", params={"from": frm, "to": to}, headers=org.headers()).json()
    assert [f["properties"]["seq"] for f in page["features"]] == [11, 12, 13, 14, 15]
    assert page["next_offset"] is None
    chart = client.get(f"{base}/telemetry?limit=5", headers=org.headers()).json()
    assert chart["seq"] == [26, 27, 28, 29, 30]
    assert chart["speed_raw_m_s"] == [1.5] * 5 and chart["actual_shaft_rpm"] == [30.0] * 5
    assert client.get(f"{base}/track", headers=other.headers()).status_code == 404
    assert client.get(f"{base}/telemetry", headers=fx.device_headers).status_code == 403
    bad = client.get(f"{base}/track", params={"from": to, "to": frm}, headers=org.headers())
    assert bad.status_code == 422


def test_no_data_ends_when_the_job_stops(client, db, org) -> None:  # noqa: ANN001
    fx = make_job(org.id, state="running")  # running, never heard from
    client.get("/api/v1/machines/status", headers=org.headers())
    (a,) = _alerts(client, org, fx, active=True)
    assert a["kind"] == "no_data"
    r = client.post(
        f"/api/v1/jobs/{fx.job_id}/state", json={"state": "paused"}, headers=org.headers()
    )
    assert r.status_code == 200
    client.get("/api/v1/machines/status", headers=org.headers())
    assert _alerts(client, org, fx, active=True) == []


def test_fleet_isolation(client, make_org) -> None:  # noqa: ANN001
    a, b = make_org(), make_org()
    fa, fb = make_job(a.id, state="running"), make_job(b.id, state="running")
    _post(client, fb, [record(fb, 1)])
    ids = [
        m["machine_id"]
        for m in client.get("/api/v1/machines/status", headers=a.headers()).json()["items"]
    ]
    assert ids == [fa.machine_id]
    alerts = client.get("/api/v1/alerts", headers=a.headers()).json()["items"]
    assert [x["machine_id"] for x in alerts] == [fa.machine_id]  # fa's no_data, nothing of b
    # device tokens cannot use the people's fleet and report endpoints
    for path in (
        "/api/v1/machines/status",
        "/api/v1/alerts",
        f"/api/v1/jobs/{fa.job_id}/report",
        f"/api/v1/jobs/{fa.job_id}/summary",
        f"/api/v1/machines/{fa.machine_id}/track",
    ):
        assert client.get(path, headers=fa.device_headers).status_code == 403, path
    assert (
        client.get(f"/api/v1/machines/{fb.machine_id}/telemetry", headers=a.headers()).status_code
        == 404
    )


def test_track_by_day_in_the_farms_time_zone(client, make_org) -> None:  # noqa: ANN001
    """Route history by day: the days are local, and each day's bounds fetch exactly that
    day's track (a record 30 min after UTC midnight is still the previous day in New York)."""
    org, other = make_org(), make_org()
    fx = make_job(org.id, state="running")
    utc = dt.UTC
    times = [
        dt.datetime(2026, 6, 1, 10, 0, tzinfo=utc),  # 1 June in UTC and in New York
        dt.datetime(2026, 6, 1, 11, 0, tzinfo=utc),
        dt.datetime(2026, 6, 2, 0, 30, tzinfo=utc),  # 2 June UTC, 1 June 20:30 in New York
        dt.datetime(2026, 6, 3, 9, 0, tzinfo=utc),
    ]
    _post(client, fx, [record(fx, i + 1, t=x.timestamp()) for i, x in enumerate(times)])
    base = f"/api/v1/machines/{fx.machine_id}/track"
    h = org.headers("viewer")

    def days(tz: str) -> list[dict]:
        r = client.get(f"{base}/days", params={"tz": tz}, headers=h)
        assert r.status_code == 200, r.text
        return r.json()["items"]

    assert [(d["day"], d["points"]) for d in days("UTC")] == [
        ("2026-06-03", 1),
        ("2026-06-02", 1),
        ("2026-06-01", 2),
    ]
    ny = days("America/New_York")
    assert [(d["day"], d["points"]) for d in ny] == [("2026-06-03", 1), ("2026-06-01", 3)]
    june1 = ny[1]
    assert june1["start"].startswith("2026-06-01T00:00:00") and june1["start"].endswith("-04:00")
    page = client.get(base, params={"from": june1["start"], "to": june1["end"]}, headers=h).json()
    assert [f["properties"]["seq"] for f in page["features"]] == [1, 2, 3]
    assert page["total"] == 3
    bad = client.get(f"{base}/days", params={"tz": "Mars/Olympus"}, headers=h)
    assert bad.status_code == 422 and "Mars/Olympus" in bad.text
    assert client.get(f"{base}/days", headers=other.headers()).status_code == 404


def test_status_keeps_last_seen_and_position_when_offline(client, db, org) -> None:  # noqa: ANN001
    """The fleet list shows "offline, last seen 5 min ago" at the last known place: an
    offline machine keeps its last_seen_at, silent_s and position (only live figures go)."""
    fx = make_job(org.id, state="running")
    _post(client, fx, [record(fx, 1, t=time.time())])
    (m,) = client.get("/api/v1/machines/status", headers=org.headers()).json()["items"]
    assert m["online"] and m["silent_s"] < 30 and m["last_seen_at"] is not None
    db.execute(
        text(
            "UPDATE machine_status SET last_seen_at = now() - interval '5 minutes'"
            " WHERE machine_id = :m"
        ),
        {"m": fx.machine_id},
    )
    db.commit()
    body = client.get("/api/v1/machines/status", headers=org.headers()).json()
    (m,) = body["items"]
    assert not m["online"] and m["state"] == "offline"
    assert 299 <= m["silent_s"] < 330
    seen = dt.datetime.fromisoformat(m["last_seen_at"])
    now = dt.datetime.fromisoformat(body["server_time"])
    assert 299 <= (now - seen).total_seconds() < 330
    assert m["position"]["coordinates"] == [fx.cells[0]["lon"], fx.cells[0]["lat"]]
    assert m["speed_m_s"] is None and m["last_speed_m_s"] == 1.5
