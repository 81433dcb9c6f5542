"""Tenancy: every resource of organisation A is invisible (404) to organisation B.

Each entry of RESOURCES creates one resource as A and lists the requests B
must not be able to make on it. Routers added later add their resources here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import pytest

from tests.support import SMALL_PLOT, feature, machine_body


@dataclass
class Resource:
    name: str
    create: Callable  # (client, headers) -> id
    item: str  # path template with {id}
    patch: dict | None = None
    extra_get: list[str] = field(default_factory=list)  # more GET paths with {id}
    extra_post: list[tuple[str, dict]] = field(default_factory=list)


def _create(path: str, body: dict) -> Callable:
    def go(client, headers) -> int:  # noqa: ANN001
        r = client.post(path, headers=headers, json=body)
        assert r.status_code == 201, r.text
        return r.json()["id"]

    return go


RESOURCES = [
    Resource(
        "farm", _create("/api/v1/farms", {"name": "A farm"}), "/api/v1/farms/{id}", {"name": "x"}
    ),
    Resource(
        "field",
        _create("/api/v1/fields", feature(SMALL_PLOT)),
        "/api/v1/fields/{id}",
        {"properties": {"name": "x"}},
    ),
    Resource(
        "machine",
        _create("/api/v1/machines", machine_body("M")),
        "/api/v1/machines/{id}",
        {"name": "x"},
        extra_post=[("/api/v1/machines/{id}/device-token", {})],
    ),
]


@pytest.mark.parametrize("res", RESOURCES, ids=lambda r: r.name)
def test_other_organisation_gets_404(client, make_org, res: Resource) -> None:
    a, b = make_org(), make_org()
    rid = res.create(client, a.headers("admin"))
    hb = b.headers("admin")
    path = res.item.format(id=rid)
    assert client.get(path, headers=a.headers("viewer")).status_code == 200
    assert client.get(path, headers=hb).status_code == 404
    for extra in res.extra_get:
        assert client.get(extra.format(id=rid), headers=hb).status_code == 404, extra
    for extra, body in res.extra_post:
        assert client.post(extra.format(id=rid), headers=hb, json=body).status_code == 404, extra
    if res.patch is not None:
        assert client.patch(path, headers=hb, json=res.patch).status_code == 404
    assert client.delete(path, headers=hb).status_code == 404
    assert client.get(path, headers=a.headers("viewer")).status_code == 200  # still there


def test_lists_are_scoped(client, make_org) -> None:
    a, b = make_org(), make_org()
    for res in RESOURCES:
        res.create(client, a.headers("admin"))
    assert client.get("/api/v1/fields", headers=b.headers()).json()["total"] == 0
    assert client.get("/api/v1/farms", headers=b.headers()).json()["total"] == 0
    assert client.get("/api/v1/machines", headers=b.headers()).json()["total"] == 0
    assert client.get("/api/v1/fields", headers=a.headers()).json()["total"] == 1


def test_viewer_cannot_write_anything(client, org) -> None:
    hv = org.headers("viewer")
    for res in RESOURCES:
        rid = res.create(client, org.headers("admin"))
        path = res.item.format(id=rid)
        if res.patch is not None:
            assert client.patch(path, headers=hv, json=res.patch).status_code == 403
        assert client.delete(path, headers=hv).status_code == 403
