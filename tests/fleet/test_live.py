"""Two API processes: a browser-like WebSocket client on one, telemetry posted to the other."""

from __future__ import annotations

import asyncio
import json
import time

import httpx
import websockets

from tests.fleet.helpers import make_job, record
from tests.fleet.procs import start_api


def test_live_across_two_api_processes(database_url, make_org) -> None:  # noqa: ANN001
    org, other = make_org(), make_org()
    fx = make_job(org.id, state="running")
    fo = make_job(other.id, state="running")
    a, url_a = start_api(database_url)
    b, url_b = start_api(database_url)
    try:

        async def scenario() -> list[tuple[float, dict]]:
            ws_url = url_a.replace("http", "ws") + f"/api/v1/live?token={org.tokens['viewer']}"
            got: list[tuple[float, dict]] = []
            async with websockets.connect(ws_url) as ws:
                hello = json.loads(await asyncio.wait_for(ws.recv(), 5))
                assert hello["type"] == "status"
                assert [m["machine_id"] for m in hello["machines"]] == [fx.machine_id]
                async with httpx.AsyncClient(base_url=url_b) as client:
                    # the other organisation's telemetry must not reach this browser
                    r = await client.post(
                        "/api/v1/telemetry",
                        json={"records": [record(fo, 1)]},
                        headers=fo.device_headers,
                    )
                    assert r.status_code == 200
                    t0 = time.monotonic()
                    r = await client.post(
                        "/api/v1/telemetry",
                        json={
                            "records": [
                                record(fx, 1, cell=2),
                                {**record(fx, 2, cell=2), "ndvi": 0.42},
                            ]
                        },
                        headers=fx.device_headers,
                    )
                    assert r.json()["acked_seq"] == 2
                while True:
                    msg = json.loads(await asyncio.wait_for(ws.recv(), 2))
                    got.append((time.monotonic() - t0, msg))
                    if msg["type"] == "position":
                        return got

        got = asyncio.run(scenario())
    finally:
        a.stop()
        b.stop()
    dt_s, pos = got[-1]
    assert dt_s < 1.0
    assert pos["machine_id"] == fx.machine_id and pos["seq"] == 2 and pos["cell_seq"] == 2
    assert abs(pos["lon"] - fx.cells[2]["lon"]) < 1e-9
    assert "org" not in pos
    assert pos["ndvi"] == 0.42 and pos["depth_mm"] is None  # the sensor-job figures
    assert all(m.get("machine_id") == fx.machine_id for _, m in got)


def test_live_rejects_bad_and_device_tokens(database_url, client, org) -> None:  # noqa: ANN001
    from starlette.websockets import WebSocketDisconnect

    fx = make_job(org.id)
    for token in ("nope", fx.device_token):
        try:
            with client.websocket_connect(f"/api/v1/live?token={token}") as ws:
                ws.receive_text()
            raise AssertionError("connected")
        except WebSocketDisconnect as exc:
            assert exc.code == 4401
