"""Tenancy of plans, soil, prescriptions and tiles: other org -> 404, viewer read-only,
device tokens refused."""

from __future__ import annotations

from tests.support import machine_body
from tests.support.plans import API
from tests.support.prescriptions import make_rx, samples_csv, setup_plan


def _world(client, org):
    h = org.headers("admin")
    plan = setup_plan(client, h, samples_csv([100.0], grid=2))
    rx = make_rx(client, h, plan["id"], model="uniform", params={"rate_kg_ha": 100})
    return plan, rx


def _reads(plan, rx):
    p, r, f = plan["id"], rx["id"], plan["field_id"]
    return [
        f"{API}/plans/{p}",
        f"{API}/fields/{f}/plans",
        f"{API}/plans/{p}/cells",
        f"{API}/plans/{p}/route",
        f"{API}/plans/{p}/prescriptions",
        f"{API}/tiles/plans/{p}/12/3300/1680.mvt",
        f"{API}/fields/{f}/soil-samples",
        f"{API}/prescriptions/{r}",
        f"{API}/prescriptions/{r}/versions",
        f"{API}/prescriptions/{r}/versions/1",
        f"{API}/prescriptions/{r}/cells",
        f"{API}/prescriptions/{r}/export?format=csv",
        f"{API}/tiles/prescriptions/{r}/1/12/3300/1680.mvt",
    ]


def _writes(plan, rx):
    p, r, f = plan["id"], rx["id"], plan["field_id"]
    edit = {"cells": [{"seq": 0, "rate_kg_ha": 1}]}
    return [
        ("post", f"{API}/fields/{f}/plans", {}),
        (
            "post",
            f"{API}/plans/{p}/prescriptions",
            {"model": "uniform", "params": {"rate_kg_ha": 1}},
        ),
        ("post", f"{API}/prescriptions/{r}/edits", edit),
        ("delete", f"{API}/prescriptions/{r}", None),
        ("delete", f"{API}/fields/{f}/soil-samples", None),
        ("delete", f"{API}/plans/{p}", None),
    ]


def _call(client, method, url, headers, body):
    if method == "post":
        return client.post(url, headers=headers, json=body)
    return client.delete(url, headers=headers)


def test_other_organisation_sees_nothing(client, make_org) -> None:
    a, b = make_org(), make_org()
    plan, rx = _world(client, a)
    for url in _reads(plan, rx):
        assert client.get(url, headers=a.headers("viewer")).status_code == 200, url
        assert client.get(url, headers=b.headers("admin")).status_code == 404, url
    for method, url, body in _writes(plan, rx):
        assert _call(client, method, url, b.headers("admin"), body).status_code == 404, url
    listed = client.get(f"{API}/prescriptions", headers=b.headers()).json()
    assert listed["total"] == 0
    assert (
        client.get(f"{API}/prescriptions/{rx['id']}", headers=a.headers()).json()["current_version"]
        == 1
    )


def test_viewer_cannot_write(client, org) -> None:
    plan, rx = _world(client, org)
    for method, url, body in _writes(plan, rx):
        assert _call(client, method, url, org.headers("viewer"), body).status_code == 403, url
    assert client.get(f"{API}/plans/{plan['id']}", headers=org.headers()).status_code == 200


def test_device_token_is_refused(client, org) -> None:
    plan, rx = _world(client, org)
    m = client.post(f"{API}/machines", headers=org.headers(), json=machine_body("M"))
    tok = client.post(f"{API}/machines/{m.json()['id']}/device-token", headers=org.headers("admin"))
    assert tok.status_code in (200, 201), tok.text
    dh = {"Authorization": f"Bearer {tok.json()['token']}"}
    for url in _reads(plan, rx):
        assert client.get(url, headers=dh).status_code == 403, url
    for method, url, body in _writes(plan, rx):
        assert _call(client, method, url, dh, body).status_code == 403, url
