"""Management zones from soil samples (POST /plans/{id}/zones): the model's input property
interpolated onto the cells, zoned by the same classifier and smoothing as imagery NDVI
zones, one model rate per zone, stored as a versioned prescription."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from fieldrx.agronomy.ratemodels.ndvi import ndvi_linear_rate
from fieldrx.agronomy.ratemodels.nutrient_balance import nutrient_balance_rate
from fieldrx.db.models import Prescription
from pyproj import Transformer
from shapely.geometry import shape
from sqlalchemy import func, select

from tests.support.plans import API
from tests.support.prescriptions import all_cells, samples_csv, setup_plan

NB = {"target_yield_kg_ha": 2500, "n_fraction": 0.25}
TO_UTM = Transformer.from_crs(4326, 32649, always_xy=True)


def _utm(cells: list[dict]) -> np.ndarray:
    polys = np.array([shape(c["geometry"]) for c in cells], dtype=object)
    return shapely.transform(
        polys, lambda xy: np.column_stack(TO_UTM.transform(xy[:, 0], xy[:, 1]))
    )


def _patch_areas(cells: list[dict]) -> list[float]:
    """Area (m^2) of every connected patch of cells sharing one zone value."""
    polys = _utm(cells)
    zone = np.array([c["properties"]["source_value"] for c in cells], dtype=float)
    out: list[float] = []
    for v in np.unique(zone[np.isfinite(zone)]):
        merged = shapely.union_all(shapely.buffer(polys[zone == v], 0.01))
        out.extend(g.area for g in getattr(merged, "geoms", [merged]))
    return out


def _zones(client, org, plan_id: int, **body) -> dict:  # noqa: ANN001
    r = client.post(f"{API}/plans/{plan_id}/zones", headers=org.headers(), json=body)
    assert r.status_code == 201, r.text
    return r.json()


def test_soil_n_zones_one_rate_per_zone_west_to_east(client, org) -> None:
    """Soil N rising west -> east (samples_csv: 60 + 10 per column): 3 zones ordered by N,
    each zone's cells at the nutrient-balance rate of the zone's mean N; exported as ISOXML
    treatment zones; a zone edit makes version 2 and leaves version 1."""
    plan = setup_plan(client, org.headers(), samples_csv())
    rx = _zones(
        client, org, plan["id"], model="nutrient_balance", params=NB, interpolation="idw", k=3
    )
    assert rx["model"] == "nutrient_balance" and rx["current_version"] == 1
    interp = rx["summary"]["interpolation"]
    assert interp["method"] == "idw" and interp["n_samples"] == 16
    assert interp["classifier"] == "kmeans_1d" and interp["zoned_value"] == "n_mg_kg"
    zones = interp["zones"]
    means = [z["mean_n_mg_kg"] for z in zones]
    assert [z["zone"] for z in zones] == [1, 2, 3] and means == sorted(means)
    assert 60 < means[0] < means[2] < 110
    cells = all_cells(client, org.headers(), rx["id"])
    assert sum(z["cells"] for z in zones) == len(cells) == plan["n_cells"]
    rates = np.array([c["properties"]["rate_kg_ha"] for c in cells])
    src = np.array([c["properties"]["source_value"] for c in cells])
    assert set(np.round(src, 9)) == set(np.round(means, 9))
    assert rates == pytest.approx(nutrient_balance_rate(src, 2500, 0.25), abs=1e-6)
    assert len(set(np.round(rates, 6))) == 3
    x = shapely.get_x(shapely.centroid(_utm(cells)))
    low, high = src == min(means), src == max(means)
    assert x[low].mean() + 20 < x[high].mean()  # low-N zone in the west
    r = client.get(
        f"{API}/prescriptions/{rx['id']}/export?format=isoxml-zones", headers=org.headers()
    )
    assert r.status_code == 200 and r.content[:2] == b"PK"
    first = cells[0]
    r = client.post(
        f"{API}/prescriptions/{rx['id']}/edits",
        headers=org.headers(),
        json={"cells": [{"seq": first["properties"]["seq"], "rate_kg_ha": 123.0}], "note": "x"},
    )
    assert r.status_code in (200, 201), r.text
    v1 = all_cells(client, org.headers(), rx["id"], version=1)
    assert v1[0]["properties"]["rate_kg_ha"] == first["properties"]["rate_kg_ha"]


def test_min_area_smoothing_removes_small_patches(client, org) -> None:
    """Noisy soil N makes small islands; with min_area_m2 every patch is at least that big
    (or the zoning says what it merged)."""
    rng = np.random.default_rng(3)
    csv = samples_csv(list(rng.uniform(40, 120, 36)), grid=6)
    plan = setup_plan(client, org.headers(), csv)
    body = {"model": "nutrient_balance", "params": NB, "interpolation": "idw", "k": 4}
    raw = _zones(client, org, plan["id"], **body)
    raw_patches = _patch_areas(all_cells(client, org.headers(), raw["id"]))
    min_area = 150.0
    assert min(raw_patches) < min_area  # the test data has islands to smooth
    smooth = _zones(client, org, plan["id"], **body, min_area_m2=min_area)
    assert smooth["summary"]["interpolation"]["merged_patches"] > 0
    patches = _patch_areas(all_cells(client, org.headers(), smooth["id"]))
    assert len(patches) < len(raw_patches)
    assert min(patches) >= min_area - 1.0


def test_sample_ndvi_zones_use_seed_000_curve(client, org) -> None:
    plan = setup_plan(client, org.headers(), samples_csv())
    rx = _zones(client, org, plan["id"], model="ndvi", interpolation="idw", k=4)
    zones = rx["summary"]["interpolation"]["zones"]
    assert "mean_ndvi" in zones[0]
    cells = all_cells(client, org.headers(), rx["id"])
    src = np.array([c["properties"]["source_value"] for c in cells])
    rates = np.array([c["properties"]["rate_kg_ha"] for c in cells])
    assert rates == pytest.approx(ndvi_linear_rate(src), abs=1e-6)
    assert len(set(np.round(rates, 6))) == 4


@pytest.mark.parametrize(
    ("csv", "body", "status", "needle"),
    [
        (True, {"model": "uniform", "params": {"rate_kg_ha": 100}}, 422, "per-cell input"),
        (True, {"model": "nutrient_balance", "params": NB, "k": 1}, 422, "k"),
        (True, {"model": "nutrient_balance", "params": NB, "k": 13}, 422, "k"),
        (True, {"model": "nutrient_balance", "params": NB, "min_area_m2": -1}, 422, "min_area"),
        (False, {"model": "nutrient_balance", "params": NB}, 422, "soil-samples"),
        (True, {"model": "nutrient_balance", "params": {"n_fraction": 0.25}}, 422, "target"),
        (
            True,
            {"model": "nutrient_balance", "params": NB, "interpolation": "nearest"},
            422,
            "interpolation",
        ),
    ],
)
def test_bad_zone_requests_store_nothing(client, org, db, csv, body, status, needle) -> None:  # noqa: ANN001
    plan = setup_plan(client, org.headers(), samples_csv() if csv else None)
    r = client.post(f"{API}/plans/{plan['id']}/zones", headers=org.headers(), json=body)
    assert r.status_code == status, r.text
    assert needle in str(r.json())
    db.rollback()
    assert db.scalar(select(func.count()).where(Prescription.plan_id == plan["id"])) == 0


def test_too_few_cells_with_data_for_k(client, org) -> None:
    """cell_mean gives a value only to cells holding a sample: 4 samples cannot make 6 zones."""
    plan = setup_plan(client, org.headers(), samples_csv(grid=2))
    r = client.post(
        f"{API}/plans/{plan['id']}/zones",
        headers=org.headers(),
        json={"model": "nutrient_balance", "params": NB, "interpolation": "cell_mean", "k": 6},
    )
    assert r.status_code == 422 and "too few for 6 zones" in r.json()["detail"]


def test_other_organisation_gets_404(client, org, make_org) -> None:
    plan = setup_plan(client, org.headers(), samples_csv())
    other = make_org()
    r = client.post(
        f"{API}/plans/{plan['id']}/zones",
        headers=other.headers(),
        json={"model": "nutrient_balance", "params": NB},
    )
    assert r.status_code == 404
