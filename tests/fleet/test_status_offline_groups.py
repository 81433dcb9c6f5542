"""Fleet status describes the present; alerts are grouped.

* a machine that stops reporting becomes "offline" after the heartbeat timeout, pushed on
  the live socket by the API process itself (no MQTT worker, no GET), and the alerts its
  last records left open are ended: before, it stayed "alarm" with its last speed;
* alerts of one kind on one job are one group, acknowledged together.
"""

from __future__ import annotations

import asyncio
import json
import time

import httpx
import websockets

from tests.fleet.helpers import make_job, record
from tests.fleet.procs import start_api
from tests.support import scaled


def test_silent_machine_goes_offline_on_the_live_socket(database_url, org) -> None:  # noqa: ANN001
    fx = make_job(org.id, state="running")
    api, url = start_api(database_url, env={"FIELDRX_HEARTBEAT_TIMEOUT_S": "1.5"})
    try:

        async def scenario() -> list[dict]:
            ws_url = url.replace("http", "ws") + f"/api/v1/live?token={org.tokens['viewer']}"
            got: list[dict] = []
            async with websockets.connect(ws_url) as ws:
                hello = json.loads(await asyncio.wait_for(ws.recv(), 5))
                assert hello["type"] == "status"
                t0 = time.time() - 7.0  # 7 s of records, 20 % under target: a rate alert
                recs = [
                    record(fx, s, t=t0 + (s - 1) * 0.1, applied_rate_kg_ha=240.0,
                           alarms=["speed_out_of_range"])
                    for s in range(1, 71)
                ]  # fmt: skip
                async with httpx.AsyncClient(base_url=url) as client:
                    r = await client.post(
                        "/api/v1/telemetry", json={"records": recs}, headers=fx.device_headers
                    )
                    assert r.status_code == 200, r.text
                deadline = time.monotonic() + scaled(12.0)
                while time.monotonic() < deadline:
                    try:
                        msg = json.loads(await asyncio.wait_for(ws.recv(), 1.0))
                    except TimeoutError:
                        continue
                    got.append(msg)
                    if msg.get("type") == "machine" and msg.get("event") == "offline":
                        return got
            return got

        got = asyncio.run(scenario())
        status = httpx.get(
            f"{url}/api/v1/machines/status", headers=org.headers("viewer"), timeout=scaled(10)
        ).json()
        alerts = httpx.get(
            f"{url}/api/v1/alerts",
            params={"kind": "rate_error"},
            headers=org.headers(),
            timeout=scaled(10),
        ).json()["items"]
    finally:
        api.stop()
    kinds = [(m.get("type"), m.get("event"), m.get("kind")) for m in got]
    assert ("alert", "started", "rate_error") in kinds
    offline = got[-1]
    assert offline["type"] == "machine" and offline["event"] == "offline", kinds
    assert offline["machine_id"] == fx.machine_id and "org" not in offline
    # the rate alert the last records left open ended when the machine fell silent
    assert ("alert", "ended", "rate_error") in kinds
    (a,) = alerts
    assert a["active"] is False
    (m,) = [m for m in status["items"] if m["machine_id"] == fx.machine_id]
    assert m["online"] is False and m["state"] == "offline"
    assert m["speed_m_s"] is None and m["last_speed_m_s"] == 1.5
    assert m["alarms"] == [] and m["target_rate_kg_ha"] is None


def test_status_state_is_the_present(client, org) -> None:  # noqa: ANN001
    """A turn with the implement raised and an old record flag: not "alarm" (no alert)."""
    fx = make_job(org.id, state="running")
    recs = [
        record(fx, s, implement_down=False, speed_filtered_m_s=0.5, speed_raw_m_s=0.5,
               alarms=["speed_out_of_range"])
        for s in range(1, 40)
    ]  # fmt: skip
    assert (
        client.post(
            "/api/v1/telemetry", json={"records": recs}, headers=fx.device_headers
        ).status_code
        == 200
    )
    (m,) = client.get("/api/v1/machines/status", headers=org.headers()).json()["items"]
    assert m["online"] and m["active_alerts"] == 0
    assert m["state"] == "working"


def _toggle_rate(client, fx, times: int) -> None:  # noqa: ANN001
    """``times`` rate alerts: 6 s off target, then back on target, again and again."""
    seq, t = 1, 1_790_000_000.0
    for _ in range(times):
        recs = []
        for k in range(65):
            off = k < 60
            recs.append(record(fx, seq, t=t, applied_rate_kg_ha=240.0 if off else 300.0))
            seq += 1
            t += 0.1
        r = client.post("/api/v1/telemetry", json={"records": recs}, headers=fx.device_headers)
        assert r.status_code == 200, r.text


def test_alerts_grouped_per_job_and_kind_and_acknowledged_together(client, make_org) -> None:  # noqa: ANN001
    org, other = make_org(), make_org()
    fx = make_job(org.id, state="running")
    _toggle_rate(client, fx, 4)
    items = client.get("/api/v1/alerts", params={"job_id": fx.job_id}, headers=org.headers())
    assert items.json()["total"] == 4
    r = client.get("/api/v1/alerts/groups", params={"job_id": fx.job_id}, headers=org.headers())
    assert r.status_code == 200, r.text
    (g,) = r.json()["items"]
    assert (g["kind"], g["job_id"], g["machine_id"]) == ("rate_error", fx.job_id, fx.machine_id)
    assert g["count"] == 4 and g["unacknowledged"] == 4 and g["acknowledged"] is False
    assert len(g["alert_ids"]) == 4 and "rate" in g["message"]
    body = {"machine_id": fx.machine_id, "job_id": fx.job_id, "kind": "rate_error"}
    assert (
        client.post("/api/v1/alerts/ack", json=body, headers=org.headers("viewer")).status_code
        == 403
    )
    assert client.post("/api/v1/alerts/ack", json=body, headers=other.headers()).status_code == 404
    bad = client.post("/api/v1/alerts/ack", json={**body, "kind": "nope"}, headers=org.headers())
    assert bad.status_code == 422 and "nope" in bad.text
    r = client.post("/api/v1/alerts/ack", json=body, headers=org.headers())
    assert r.status_code == 200, r.text
    assert r.json()["acknowledged"] == 4
    again = client.post("/api/v1/alerts/ack", json=body, headers=org.headers()).json()
    assert again["acknowledged"] == 0
    unacked = client.get(
        "/api/v1/alerts", params={"job_id": fx.job_id, "acknowledged": False}, headers=org.headers()
    ).json()
    assert unacked["total"] == 0
    (g,) = client.get(
        "/api/v1/alerts/groups", params={"job_id": fx.job_id}, headers=org.headers()
    ).json()["items"]
    assert g["acknowledged"] is True and g["unacknowledged"] == 0
    open_groups = client.get(
        "/api/v1/alerts/groups", params={"acknowledged": False}, headers=org.headers()
    ).json()
    assert open_groups["items"] == []
    assert client.get("/api/v1/alerts/groups", headers=other.headers()).json()["items"] == []
