"""The typed API contract: the OpenAPI document is valid and complete, the
browser's generated client is current, bodies are strict, errors have one shape, and the
docs are served from the app itself.

The staleness test is the build's guard: a route or model changed without running
``scripts/gen-api.sh`` fails here (the UI would otherwise call the old contract).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.support import scaled

ROOT = Path(__file__).resolve().parents[2]
FRONTEND = ROOT / "frontend"
API = "/api/v1"
NODE = shutil.which("node")
needs_node = pytest.mark.skipif(
    NODE is None or not (FRONTEND / "node_modules" / "openapi-typescript").is_dir(),
    reason="node and frontend/node_modules (npm ci) are needed",
)


@pytest.fixture(scope="module")
def document(app) -> dict:  # noqa: ANN001
    return app.openapi()


def test_committed_openapi_document_is_current(app) -> None:  # noqa: ANN001
    from fieldrx.apidocs import openapi_json

    committed = (FRONTEND / "src/api/openapi.json").read_text()
    assert committed == openapi_json(app), (
        "frontend/src/api/openapi.json is stale: run scripts/gen-api.sh and commit the result"
    )


@needs_node
def test_generated_client_is_current(tmp_path: Path) -> None:
    """schema.ts is what openapi-typescript makes of the committed document (same flags as
    scripts/gen-api.sh)."""
    script = (ROOT / "scripts/gen-api.sh").read_text()
    flags = re.search(r"-o src/api/generated/schema.ts (.*?) >/dev/null", script)
    assert flags, "scripts/gen-api.sh no longer runs openapi-typescript as expected"
    out = tmp_path / "schema.ts"
    subprocess.run(
        ["npx", "--no-install", "openapi-typescript", "src/api/openapi.json", "-o", str(out)]
        + flags.group(1).split(),
        cwd=FRONTEND,
        check=True,
        capture_output=True,
        timeout=scaled(120),
    )
    committed = (FRONTEND / "src/api/generated/schema.ts").read_text()
    assert committed == out.read_text(), (
        "frontend/src/api/generated/schema.ts is stale: run scripts/gen-api.sh and commit it"
    )


@needs_node
def test_openapi_document_validates(tmp_path: Path, document: dict) -> None:
    """OpenAPI 3.1 structure, refs, unique operation ids, security on every operation."""
    doc = tmp_path / "openapi.json"
    doc.write_text(json.dumps(document))
    r = subprocess.run(
        [NODE or "node", "scripts/validate-openapi.mjs", str(doc)],
        cwd=FRONTEND,
        capture_output=True,
        text=True,
        timeout=scaled(120),
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert "0 problem(s)" in r.stdout


@needs_node
def test_validator_finds_a_broken_document(tmp_path: Path, document: dict) -> None:
    """The validation above can fail: a response without description and a parameter in a
    place OpenAPI does not have are reported."""
    bad = json.loads(json.dumps(document))
    op = bad["paths"][f"{API}/farms"]["get"]
    del op["responses"]["200"]["description"]
    op["parameters"][0]["in"] = "nowhere"
    doc = tmp_path / "bad.json"
    doc.write_text(json.dumps(bad))
    r = subprocess.run(
        [NODE or "node", "scripts/validate-openapi.mjs", str(doc)],
        cwd=FRONTEND,
        capture_output=True,
        text=True,
        timeout=scaled(120),
    )
    assert r.returncode == 1 and "2 problem(s)" in r.stdout, r.stdout


PUBLIC = {("get", f"{API}/health"), ("post", f"{API}/auth/login")}


def test_every_operation_is_typed_secured_and_documents_errors(document: dict) -> None:
    assert document["components"]["securitySchemes"]["bearer"] == {
        "type": "http",
        "scheme": "bearer",
        "bearerFormat": "opaque token",
        "description": document["components"]["securitySchemes"]["bearer"]["description"],
    }
    problems = []
    n = 0
    for path, ops in document["paths"].items():
        for method, op in ops.items():
            n += 1
            where = f"{method.upper()} {path}"
            ok = {c: r for c, r in op["responses"].items() if c.startswith("2")}
            for code, resp in ok.items():
                if code == "204":
                    continue
                content = resp.get("content") or {}
                if not content or any(not v.get("schema") for v in content.values()):
                    problems.append(f"{where}: {code} has no response schema")
                if "application/json" in content and content["application/json"]["schema"] == {}:
                    problems.append(f"{where}: {code} is untyped JSON")
            if (method, path) in PUBLIC:
                if op.get("security") != []:
                    problems.append(f"{where}: public operation not marked security: []")
                continue
            if op.get("security") != [{"bearer": []}]:
                problems.append(f"{where}: no bearer security")
            for code in ("401", "403", "404", "422"):
                schema = op["responses"].get(code, {}).get("content", {}).get("application/json")
                if schema != {"schema": {"$ref": "#/components/schemas/ErrorOut"}}:
                    problems.append(f"{where}: {code} not documented as ErrorOut")
            body = op.get("requestBody", {}).get("content", {}).get("application/json")
            if body and path != f"{API}/telemetry":
                name = body["schema"]["$ref"].rsplit("/", 1)[-1]
                model = document["components"]["schemas"][name]
                if model.get("additionalProperties") is not False:
                    problems.append(f"{where}: request body {name} accepts unknown fields")
    assert n > 60
    assert not problems, "\n".join(problems)


def test_exports_declare_their_file_types(document: dict) -> None:
    paths = document["paths"]
    rx = paths[f"{API}/prescriptions/{{rx_id}}/export"]["get"]["responses"]["200"]["content"]
    assert set(rx) == {"application/geo+json", "text/csv", "application/zip"}
    job = paths[f"{API}/jobs/{{job_id}}/export"]["get"]["responses"]["200"]["content"]
    assert set(job) == {"text/csv", "application/zip"}
    tile = paths[f"{API}/tiles/plans/{{plan_id}}/{{z}}/{{x}}/{{y}}.mvt"]["get"]["responses"]
    assert set(tile["200"]["content"]) == {"application/vnd.mapbox-vector-tile"}
    png = paths[f"{API}/tiles/imagery/{{imagery_id}}/{{z}}/{{x}}/{{y}}.png"]["get"]["responses"]
    assert set(png["200"]["content"]) == {"image/png"}


def test_one_name_per_field(document: dict) -> None:
    """A prescription says its version once (current_version), a plan its parameters once."""
    schemas = document["components"]["schemas"]
    rx = schemas["PrescriptionOut"]["properties"]
    assert "current_version" in rx
    assert not {"version", "latest_version"} & set(rx)
    plan = schemas["PlanOut"]["properties"]
    assert not {"heading_rule", "stats", "swath_width_m", "cell_length_m"} & set(plan)
    cell = schemas["RxCellProps"]["properties"]
    assert not {"clamped", "flag"} & set(cell)
    assert "version" not in schemas["JobIn"]["properties"]


def test_unknown_body_field_is_refused_naming_it(client, org) -> None:  # noqa: ANN001
    h = org.headers("agronomist")
    r = client.post(f"{API}/farms", headers=h, json={"name": "North", "nmae": "typo"})
    assert r.status_code == 422, r.text
    body = r.json()
    assert body["where"] == "nmae" and "nmae: unknown field" in body["detail"], body
    assert client.get(f"{API}/farms", headers=h).json()["total"] == 0  # nothing stored
    r = client.post(
        f"{API}/fields/1/plans", headers=h, json={"swath_width_m": 12, "headland_pases": 1}
    )
    assert r.status_code == 422 and r.json()["where"] == "headland_pases", r.text


def test_errors_have_one_shape(client, org) -> None:  # noqa: ANN001
    h = org.headers("agronomist")
    answers = [
        client.get(f"{API}/farms"),  # 401
        client.post(f"{API}/farms", headers=org.headers("viewer"), json={"name": "x"}),  # 403
        client.get(f"{API}/farms/999999999", headers=h),  # 404
        client.post(f"{API}/farms", headers=h, json={}),  # 422 (validation)
        client.post(f"{API}/jobs/999999999/state", headers=h, json={"state": "sent"}),  # 404
    ]
    assert [a.status_code for a in answers] == [401, 403, 404, 422, 404]
    for a in answers:
        body = a.json()
        assert isinstance(body["detail"], str) and body["detail"], body
        assert set(body) <= {"detail", "where", "errors", "allowed", "state"}, body


def test_token_without_role_may_write_and_viewer_403_says_how(client, org) -> None:  # noqa: ANN001
    r = client.post(f"{API}/auth/tokens", headers=org.headers("admin"), json={"name": "script"})
    assert r.status_code == 201, r.text
    assert r.json()["role"] == "agronomist"
    th = {"Authorization": f"Bearer {r.json()['token']}"}
    assert client.post(f"{API}/farms", headers=th, json={"name": "first write"}).status_code == 201
    viewer = client.post(f"{API}/auth/tokens", headers=org.headers("viewer"), json={"name": "v"})
    assert viewer.status_code == 201 and viewer.json()["role"] == "viewer"
    r = client.post(
        f"{API}/farms",
        headers={"Authorization": f"Bearer {viewer.json()['token']}"},
        json={"name": "x"},
    )
    assert r.status_code == 403
    detail = r.json()["detail"]
    assert "'agronomist' or 'admin'" in detail and "POST /api/v1/auth/tokens" in detail, detail
    r = client.post(
        f"{API}/auth/tokens", headers=org.headers("viewer"), json={"name": "v", "role": "admin"}
    )
    assert r.status_code == 403 and "at most its creator's role" in r.json()["detail"]


def test_docs_are_served_from_the_app(client) -> None:  # noqa: ANN001
    for page, asset in (("/docs", "swagger-ui-bundle.js"), ("/redoc", "redoc.standalone.js")):
        r = client.get(page)
        assert r.status_code == 200, page
        html = r.text
        assert f"/docs-assets/{asset}" in html
        assert not re.search(r"(src|href)=[\"']?(https?:)?//", html), html  # no CDN
        csp = r.headers["content-security-policy"]
        assert "connect-src 'self'" in csp and "https:" not in csp
        js = client.get(f"/docs-assets/{asset}")
        assert js.status_code == 200 and len(js.content) > 500_000
    assert "First call" in client.get(f"{API}/openapi.json").json()["info"]["description"]


def test_first_call_guide_works(client, org) -> None:  # noqa: ANN001
    """The docs' (docs/api.md) / OpenAPI description's first call, step by step, with a token made
    without a role: field, plan, prescription, ISOXML."""
    r = client.post(f"{API}/auth/tokens", headers=org.headers("agronomist"), json={"name": "s"})
    h = {"Authorization": f"Bearer {r.json()['token']}"}
    ring = [[112.32, 32.13], [112.3237, 32.13], [112.3237, 32.1321], [112.32, 32.1321]]
    field = client.post(
        f"{API}/fields",
        headers=h,
        json={
            "type": "Feature",
            "properties": {"name": "North"},
            "geometry": {"type": "Polygon", "coordinates": [[*ring, ring[0]]]},
        },
    )
    assert field.status_code == 201, field.text
    plan = client.post(
        f"{API}/fields/{field.json()['id']}/plans",
        headers=h,
        json={"swath_width_m": 12, "cell_length_m": 10},
    )
    assert plan.status_code == 201, plan.text
    rx = client.post(
        f"{API}/plans/{plan.json()['id']}/prescriptions",
        headers=h,
        json={"model": "uniform", "params": {"rate_kg_ha": 150}},
    )
    assert rx.status_code == 201, rx.text
    assert rx.json()["summary"]["rate_mean_kg_ha"] == 150
    out = client.get(f"{API}/prescriptions/{rx.json()['id']}/export?format=isoxml", headers=h)
    assert out.status_code == 200 and out.headers["content-type"] == "application/zip"
    assert out.content[:2] == b"PK"
