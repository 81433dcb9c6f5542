"""Fields and waits shared by the background-task tests."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from tests.support import feature, scaled


def rect(i: int, width_m: float, height_m: float) -> dict[str, Any]:
    """A width x height m rectangle, the i-th of a row of them near the demo farm."""
    lon0 = 112.30 + i * (width_m + 50.0) / 94_400.0
    lat0 = 32.10
    dlon, dlat = width_m / 94_400.0, height_m / 110_900.0
    ring = [[lon0, lat0], [lon0 + dlon, lat0], [lon0 + dlon, lat0 + dlat], [lon0, lat0 + dlat]]
    return {"type": "Polygon", "coordinates": [[*ring, ring[0]]]}


def make_fields(client: Any, org: Any, n: int, width_m: float, height_m: float) -> list[int]:
    ids = []
    for i in range(n):
        r = client.post(
            "/api/v1/fields", headers=org.headers(), json=feature(rect(i, width_m, height_m))
        )
        assert r.status_code == 201, r.text
        ids.append(r.json()["id"])
    return ids


def wait_until(check: Callable[[], Any], timeout_s: float, what: str, step_s: float = 0.2) -> Any:
    limit_s = scaled(timeout_s)
    t_end = time.monotonic() + limit_s
    while time.monotonic() < t_end:
        value = check()
        if value:
            return value
        time.sleep(step_s)
    raise AssertionError(f"timed out after {limit_s:g} s waiting for {what}")
