"""services.jobpackage: a prescription version + machine -> a sealed JobPackage from PostGIS."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from fieldrx_edge.job_package import JobPackage

from tests.support import SEED001_CAL
from tests.support.plans import API
from tests.support.prescriptions import all_cells, make_rx, setup_plan


def test_job_package_from_database(client, org, db) -> None:
    from fieldrx.db.models import Job, Machine
    from fieldrx.services.jobpackage import build_job_package, build_package

    h = org.headers()
    plan = setup_plan(client, h)
    m = client.post(
        f"{API}/machines",
        headers=h,
        json={
            "name": "S",
            "width_m": 2.3,
            "lag_s": 1.2,
            "calibration": SEED001_CAL,
            "speed_min_m_s": 1.0,
            "speed_max_m_s": 2.0,
            "controller": {"name": "pid", "params": {"kp": 1.5}},
        },
    ).json()
    rx = make_rx(client, h, plan["id"], model="uniform", params={"rate_kg_ha": 700})
    r = client.post(
        f"{API}/prescriptions/{rx['id']}/edits",
        headers=h,
        json={"cells": [{"seq": 2, "rate_kg_ha": 650.25}]},
    )
    assert r.status_code == 201
    job = Job(
        organisation_id=org.id,
        prescription_id=rx["id"],
        prescription_version=2,
        machine_id=m["id"],
        n_cells=plan["n_cells"],
    )
    db.add(job)
    db.commit()
    pkg = build_job_package(db, job)
    assert isinstance(pkg, JobPackage) and pkg.checksum
    again = JobPackage.from_json(pkg.to_json())  # checksum verified
    assert again.n_cells == plan["n_cells"] and again.job_id == job.id
    assert pkg.seq == list(range(plan["n_cells"]))
    assert pkg.rate_kg_ha[2] == 650.25 and pkg.rate_kg_ha[0] == 700
    assert pkg.implement_width_m == 2.3 and pkg.lag_s == 1.2 and pkg.speed_max_m_s == 2.0
    assert pkg.controller.name == "pid" and pkg.utm_epsg == 32649
    # WGS84 corners enclose the stored cell polygon
    cells = all_cells(client, h, rx["id"], 2)
    c = np.asarray(pkg.corners_wgs84).reshape(-1, 4, 2)
    for i in range(0, len(cells), 7):
        quad = shapely.Polygon(c[i])
        cell = shapely.geometry.shape(cells[i]["geometry"])
        assert cell.difference(quad.buffer(1e-7)).area < 1e-12
    u = np.asarray(pkg.corners_utm).reshape(-1, 4, 2)
    assert shapely.Polygon(u[0]).area == pytest.approx(2.3 * 5.0, rel=0.11)
    # version 1 through the other entry point: the uniform rate everywhere
    v1 = build_package(db, rx["id"], 1, db.get(Machine, m["id"]))
    assert set(v1.rate_kg_ha) == {700.0}
    with pytest.raises(LookupError):
        build_package(db, rx["id"], 5, db.get(Machine, m["id"]))


def test_a_liquid_products_density_travels_in_the_job_package(client, org, db) -> None:
    """The density belongs to the product: a prescription of a liquid (a default product or
    the organisation's own) carries it into the package, so an ISOBUS volume-rate implement
    is driven without a number typed in the cab; solids carry none."""
    from fieldrx.db.models import Machine
    from fieldrx.services.jobpackage import build_package

    h = org.headers()
    plan = setup_plan(client, h)
    m = client.post(
        f"{API}/machines",
        headers=h,
        json={"name": "Sprayer", "width_m": 2.3, "lag_s": 1.0, "calibration": SEED001_CAL},
    ).json()
    machine = db.get(Machine, m["id"])
    uan = make_rx(
        client,
        h,
        plan["id"],
        model="uniform",
        params={"rate_kg_ha": 192},
        product_key="default:uan28",
    )
    pkg = build_package(db, uan["id"], None, machine)
    assert pkg.product_density_kg_l == 1.28 and pkg.rate_unit == "kg/ha"
    assert JobPackage.from_json(pkg.to_json()).product_density_kg_l == 1.28
    r = client.post(
        f"{API}/products", headers=h, json={"name": "ATS 12-0-0", "n_pct": 12, "density_kg_l": 1.32}
    )
    assert r.status_code == 201 and r.json()["density_kg_l"] == 1.32
    own = make_rx(
        client,
        h,
        plan["id"],
        model="uniform",
        params={"rate_kg_ha": 100},
        product_key=r.json()["key"],
    )
    assert build_package(db, own["id"], None, machine).product_density_kg_l == 1.32
    bad = client.post(
        f"{API}/products", headers=h, json={"name": "x", "n_pct": 1, "density_kg_l": 40}
    )
    assert bad.status_code == 422 and "density_kg_l" in bad.text
    urea = make_rx(
        client,
        h,
        plan["id"],
        model="uniform",
        params={"rate_kg_ha": 200},
        product_key="default:urea",
    )
    assert build_package(db, urea["id"], None, machine).product_density_kg_l == 0.0


def test_an_l_ha_prescription_goes_out_by_volume(client, org, db, tmp_path) -> None:
    """A liquid prescribed in l/ha: its job package carries l/ha rates (a volume-rate
    implement takes them as they are) and its ISOXML task DDI 0001 setpoints in
    0.01 mm^3/m^2 (1 l/ha = 10 000); without a product density it is refused."""
    import io
    import xml.etree.ElementTree as ET
    import zipfile

    from fieldrx.db.models import Machine
    from fieldrx.services.jobpackage import build_package

    h = org.headers()
    plan = setup_plan(client, h)
    m = client.post(
        f"{API}/machines",
        headers=h,
        json={"name": "Sprayer", "width_m": 2.3, "lag_s": 1.0, "calibration": SEED001_CAL},
    ).json()
    body = {"model": "uniform", "params": {"rate_kg_ha": 192}, "product_key": "default:uan28"}
    rx = make_rx(client, h, plan["id"], rate_unit="l/ha", **body)
    assert rx["rate_unit"] == "l/ha" and rx["density_kg_l"] == 1.28
    pkg = build_package(db, rx["id"], None, db.get(Machine, m["id"]))
    back = JobPackage.from_json(pkg.to_json())
    assert back.rate_unit == "l/ha" and back.product_density_kg_l == 1.28
    assert set(back.rate_kg_ha) == {150.0}  # 192 kg/ha / 1.28 kg/l
    r = client.get(f"{API}/prescriptions/{rx['id']}/export?format=isoxml-zones", headers=h)
    assert r.status_code == 200, r.text
    xml = zipfile.ZipFile(io.BytesIO(r.content)).read("TASKDATA/TASKDATA.XML")
    pdvs = ET.fromstring(xml).findall(".//TZN/PDV")
    assert {p.get("A") for p in pdvs} == {"0001"}
    assert {int(p.get("B") or 0) for p in pdvs} == {0, 1_500_000}
    zones = {t.get("B") for t in ET.fromstring(xml).findall(".//TZN")}
    assert "150.00 l/ha" in zones
    g = client.get(f"{API}/prescriptions/{rx['id']}/export?format=isoxml", headers=h)
    z = zipfile.ZipFile(io.BytesIO(g.content))
    grid = np.frombuffer(z.read("TASKDATA/GRD00001.BIN"), dtype="<i4")
    assert set(np.unique(grid).tolist()) <= {0, 1_500_000} and grid.max() == 1_500_000
    # the same product in kg/ha stays a mass prescription that carries the density
    kg = make_rx(client, h, plan["id"], **body)
    assert kg["rate_unit"] == "kg/ha"
    r = client.get(f"{API}/prescriptions/{kg['id']}/export?format=isoxml-zones", headers=h)
    xml = zipfile.ZipFile(io.BytesIO(r.content)).read("TASKDATA/TASKDATA.XML")
    assert {p.get("A") for p in ET.fromstring(xml).findall(".//TZN/PDV")} == {"0006"}
    for bad in ({**body, "product_key": "default:urea"}, {k: body[k] for k in ("model", "params")}):
        r = client.post(
            f"{API}/plans/{plan['id']}/prescriptions", headers=h, json={**bad, "rate_unit": "l/ha"}
        )
        assert r.status_code == 422 and "l/ha needs the density of" in r.text, r.text
    r = client.post(
        f"{API}/plans/{plan['id']}/prescriptions", headers=h, json={**body, "rate_unit": "gal/ac"}
    )
    assert r.status_code == 422 and "rate_unit" in r.text


def test_a_lot_given_with_the_prescription_converts_and_travels(client, org) -> None:
    """A product not in the catalogue (or one without the value) gets the lot values its
    unit converts through with the request; one that contradicts the catalogue's is refused
    rather than one of them silently winning. The units and their lot values are listed by
    GET /rate-units."""
    h = org.headers()
    units = client.get(f"{API}/rate-units", headers=h).json()["items"]
    lha = next(u for u in units if u["name"] == "l/ha")
    assert units[0]["name"] == "kg/ha" and units[0]["lot"] == []
    assert lha["lot"][0]["key"] == "density_kg_l" and lha["ddi_setpoint"] == 1
    plan = setup_plan(client, h)
    body = {"model": "uniform", "params": {"rate_kg_ha": 120}, "rate_unit": "l/ha"}
    rx = make_rx(client, h, plan["id"], product="Own liquid", lot={"density_kg_l": 1.2}, **body)
    assert rx["rate_unit"] == "l/ha" and rx["density_kg_l"] == 1.2
    assert rx["lot"] == {"density_kg_l": 1.2} and rx["kg_per_unit"] == 1.2
    r = client.post(
        f"{API}/plans/{plan['id']}/prescriptions",
        headers=h,
        json={**body, "product_key": "default:uan28", "lot": {"density_kg_l": 1.3}},
    )
    assert r.status_code == 422 and "lot.density_kg_l 1.3 disagrees" in r.text, r.text
    r = client.post(
        f"{API}/plans/{plan['id']}/prescriptions",
        headers=h,
        json={**body, "lot": {"density_kg_l": 9}},
    )
    assert r.status_code == 422 and "9 kg/l is outside 0.05-5" in r.text, r.text
