"""NDVI from imagery into seed 000's NDVI rate model: a prescription per cell."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
from fieldrx.agronomy.ratemodels.ndvi import ndvi_linear_rate
from pyproj import Transformer
from shapely.geometry import shape

from tests.imagery.rasters import UTM, X0, Y0, write_tiff
from tests.support.prescriptions import all_cells

W0, W1 = X0 - 10, X0 + 210  # write_tiff's NDVI: 0.2 -> 0.8 linearly over this x range


def _upload(client, org, field_id: int, path: Path, kind: str, **form: object) -> dict:  # noqa: ANN001
    with open(path, "rb") as fh:
        r = client.post(
            f"/api/v1/fields/{field_id}/imagery",
            headers=org.headers(),
            files={"file": (path.name, fh, "image/tiff")},
            data={"kind": kind, **{k: str(v) for k, v in form.items()}},
        )
    assert r.status_code == 201, r.text
    return r.json()


def _plan(client, org, field_id: int) -> dict:  # noqa: ANN001
    r = client.post(
        f"/api/v1/fields/{field_id}/plans",
        headers=org.headers(),
        json={"swath_width_m": 2.3, "cell_length_m": 5.0},
    )
    assert r.status_code == 201, r.text
    return r.json()


def test_ndvi_image_prescription(client, org, field_id, imagery_dir, tmp_path) -> None:
    img = _upload(client, org, field_id, write_tiff(tmp_path / "n.tif", "ndvi"), "ndvi")
    plan = _plan(client, org, field_id)
    r = client.post(
        f"/api/v1/imagery/{img['id']}/prescriptions",
        headers=org.headers(),
        json={"plan_id": plan["id"], "product": "urea"},
    )
    assert r.status_code == 201, r.text
    rx = r.json()
    assert rx["model"] == "ndvi" and rx["interpolation"] == "imagery"
    assert rx["summary"]["interpolation"]["imagery_id"] == img["id"]
    cells = all_cells(client, org.headers(), rx["id"])
    assert len(cells) == plan["n_cells"]
    tr = Transformer.from_crs(4326, UTM, always_xy=True)
    polys = np.array([shape(c["geometry"]) for c in cells], dtype=object)
    x = shapely.get_x(
        shapely.centroid(
            shapely.transform(polys, lambda xy: np.column_stack(tr.transform(xy[:, 0], xy[:, 1])))
        )
    )
    ndvi = np.array([c["properties"]["source_value"] for c in cells], dtype=float)
    full = np.array([c["properties"]["area_m2"] > 11.0 for c in cells])  # whole cells
    expected = 0.2 + 0.6 * (x - W0) / (W1 - W0)
    assert np.max(np.abs(ndvi[full] - expected[full])) < 0.005
    rates = np.array([c["properties"]["rate_kg_ha"] for c in cells])
    assert rates == pytest.approx(ndvi_linear_rate(ndvi), abs=1e-6)
    assert rates.max() == pytest.approx(375.0) and rates.min() == pytest.approx(180.0)


def test_partial_cover_falls_back_and_flags(client, org, field_id, imagery_dir, tmp_path) -> None:
    """An image of the west half only: east cells have no data -> fallback rate, flagged."""
    src = write_tiff(tmp_path / "w.tif", "ndvi", bounds=(X0 - 10, Y0 - 10, X0 + 100, Y0 + 110))
    img = _upload(client, org, field_id, src, "ndvi")
    plan = _plan(client, org, field_id)
    r = client.post(
        f"/api/v1/imagery/{img['id']}/prescriptions",
        headers=org.headers(),
        json={"plan_id": plan["id"], "fallback_rate_kg_ha": 250},
    )
    assert r.status_code == 201, r.text
    cells = all_cells(client, org.headers(), r.json()["id"])
    nodata = [c for c in cells if "no_data" in c["properties"]["flags"]]
    assert 0.3 * len(cells) < len(nodata) < 0.7 * len(cells)
    assert all(c["properties"]["rate_kg_ha"] == 250 for c in nodata)
    assert r.json()["stats"]["no_data_count"] == len(nodata)


def test_orthophoto_and_other_org_refused(
    client, org, make_org, field_id, imagery_dir, tmp_path
) -> None:
    ortho = _upload(client, org, field_id, write_tiff(tmp_path / "o.tif"), "orthophoto")
    plan = _plan(client, org, field_id)
    r = client.post(
        f"/api/v1/imagery/{ortho['id']}/prescriptions",
        headers=org.headers(),
        json={"plan_id": plan["id"]},
    )
    assert r.status_code == 422 and "orthophoto" in r.json()["detail"]
    other = make_org()
    r = client.post(
        f"/api/v1/imagery/{ortho['id']}/prescriptions",
        headers=other.headers(),
        json={"plan_id": plan["id"]},
    )
    assert r.status_code == 404


def test_four_zone_prescription_and_isoxml_zones(
    client, org, field_id, imagery_dir, tmp_path
) -> None:
    """NDVI 0.2 -> 0.8 west -> east: 4 zones in west -> east order, one rate per zone from
    seed 000's curve at the zone's mean NDVI; exported as ISOXML treatment zones."""
    img = _upload(client, org, field_id, write_tiff(tmp_path / "n.tif", "ndvi"), "ndvi")
    plan = _plan(client, org, field_id)
    r = client.post(
        f"/api/v1/imagery/{img['id']}/zones",
        headers=org.headers(),
        json={"plan_id": plan["id"], "k": 4, "min_area_m2": 200},
    )
    assert r.status_code == 201, r.text
    rx = r.json()
    zones = rx["summary"]["interpolation"]["zones"]
    assert [z["zone"] for z in zones] == [1, 2, 3, 4]
    means = [z["mean_ndvi"] for z in zones]
    assert means == sorted(means)
    cells = all_cells(client, org.headers(), rx["id"])
    rates = {round(c["properties"]["rate_kg_ha"], 6) for c in cells}
    assert len(rates) == 4
    expected = {round(float(ndvi_linear_rate(m)), 6) for m in means}
    assert rates == expected
    assert sum(z["cells"] for z in zones) == len(cells)
    r = client.get(
        f"/api/v1/prescriptions/{rx['id']}/export?format=isoxml-zones", headers=org.headers()
    )
    assert r.status_code == 200 and r.content[:2] == b"PK"
    r = client.post(
        f"/api/v1/imagery/{img['id']}/zones",
        headers=org.headers(),
        json={"plan_id": plan["id"], "k": 1},
    )
    assert r.status_code == 422
