"""Fixtures-as-functions for prescription tests: a field with samples and a plan."""

from __future__ import annotations

import numpy as np

from tests.support.plans import API, make_field, make_plan, rectangle

FIELD = rectangle(112.3501, 32.1501, 60, 40)  # 60 m x 40 m


def samples_csv(n_values: list[float] | None = None, grid: int = 4, seed: int = 0) -> str:
    """grid x grid samples spread over FIELD; n from n_values or a smooth gradient."""
    (lon0, lat0), (lon1, lat1) = FIELD["coordinates"][0][0], FIELD["coordinates"][0][2]
    rows = ["sample_id,lon,lat,n_mg_kg,ndvi"]
    k = 0
    rng = np.random.default_rng(seed)
    for i in range(grid):
        for j in range(grid):
            lon = lon0 + (lon1 - lon0) * (i + 0.5) / grid
            lat = lat0 + (lat1 - lat0) * (j + 0.5) / grid
            n = n_values[k % len(n_values)] if n_values else 60 + 10 * i + 5 * j + rng.normal(0, 2)
            ndvi = 0.2 + 0.1 * i
            rows.append(f"S{k},{lon:.8f},{lat:.8f},{n:.3f},{ndvi:.3f}")
            k += 1
    return "\n".join(rows) + "\n"


def setup_plan(client, headers, csv: str | None = None, **plan_params) -> dict:
    fid = make_field(client, headers, FIELD)
    if csv is not None:
        r = client.post(
            f"{API}/fields/{fid}/soil-samples",
            headers=headers,
            files={"file": ("s.csv", csv, "text/csv")},
        )
        assert r.status_code == 201, r.text
    plan = make_plan(client, headers, fid, **plan_params)
    plan["field_id"] = fid
    return plan


def make_rx(client, headers, plan_id: int, **body) -> dict:
    r = client.post(f"{API}/plans/{plan_id}/prescriptions", headers=headers, json=body)
    assert r.status_code == 201, r.text
    return r.json()


def all_cells(client, headers, rx_id: int, version: int | None = None) -> list[dict]:
    q = "?limit=50000" + (f"&version={version}" if version is not None else "")
    r = client.get(f"{API}/prescriptions/{rx_id}/cells{q}", headers=headers)
    assert r.status_code == 200, r.text
    return r.json()["features"]
