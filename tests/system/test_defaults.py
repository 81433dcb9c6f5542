"""One default per parameter, shared by the API, the CLI and the UI (defect: the API
planned 0 headland passes where the UI said 1, and interpolated with ``cell_mean`` where the
UI said ``idw``; ``cell_mean`` at ~1 sample/ha answers "no cell has data").

The home of each default is a constant next to the code that uses it; the request models
carry it into the OpenAPI document, ``scripts/gen-api.sh`` into
``frontend/src/api/generated/defaults.json``, which the forms read
(``frontend/src/api/defaults.test.ts`` checks they keep no copy).
"""

from __future__ import annotations

import argparse
import inspect
import json
from pathlib import Path

from fieldrx.agronomy.interpolate import DEFAULT_METHOD
from fieldrx.agronomy.prescription import prescribe
from fieldrx.apidocs import openapi_json, schema_defaults_json
from fieldrx.geo.coverage import plan_coverage
from fieldrx.geo.planning.kinematics import DEFAULT_HEADLAND_PASSES

from tests.support.plans import API, make_field, make_plan, rectangle

NB = {"target_yield_kg_ha": 2500, "e_kg_per_100kg": 5.8, "k_utilisation": 0.342, "n_fraction": 0.25}
ROOT = Path(__file__).resolve().parents[2]
DEFAULTS = ROOT / "frontend/src/api/generated/defaults.json"


def test_committed_defaults_file_is_current(app) -> None:  # noqa: ANN001
    assert DEFAULTS.read_text() == schema_defaults_json(openapi_json(app)), (
        "frontend/src/api/generated/defaults.json is stale: run scripts/gen-api.sh"
    )


def test_the_ui_reads_the_apis_defaults(app) -> None:  # noqa: ANN001
    ui = json.loads(DEFAULTS.read_text())
    doc = app.openapi()["components"]["schemas"]
    assert ui["PlanIn"]["headland_passes"] == DEFAULT_HEADLAND_PASSES == 0
    assert doc["PlanIn"]["properties"]["headland_passes"]["default"] == DEFAULT_HEADLAND_PASSES
    for model in ("PrescriptionIn", "SoilZonesIn"):
        assert ui[model]["interpolation"] == DEFAULT_METHOD == "idw"
        assert doc[model]["properties"]["interpolation"]["default"] == DEFAULT_METHOD


def _cli_defaults(module: str) -> dict:
    mod = __import__(f"fieldrx.commands.{module}", fromlist=["register"])
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers()
    p = mod.register(sub)
    return {a.dest: a.default for a in p._actions}


def test_every_entry_point_has_the_same_default(app) -> None:  # noqa: ANN001
    assert (
        inspect.signature(plan_coverage).parameters["headland_passes"].default
        == DEFAULT_HEADLAND_PASSES
    )
    assert inspect.signature(prescribe).parameters["interpolation"].default == DEFAULT_METHOD
    assert _cli_defaults("plan")["headland_passes"] == DEFAULT_HEADLAND_PASSES
    rx = _cli_defaults("rx")
    assert rx["headland_passes"] == DEFAULT_HEADLAND_PASSES
    assert rx["interpolation"] == DEFAULT_METHOD
    # the ISOXML import plans the imported fields: its query parameter too
    for path, item in app.openapi()["paths"].items():
        for op in item.values():
            for prm in op.get("parameters", []) if isinstance(op, dict) else []:
                if prm["name"] == "headland_passes":
                    assert prm["schema"]["default"] == DEFAULT_HEADLAND_PASSES, path


def test_default_plan_and_prescription_at_one_sample_per_hectare(client, org) -> None:
    """The defaults work together: a 2 ha field with one sample per hectare gets a
    prescription with data in every cell (``cell_mean`` gives data to the two cells that
    hold a sample, and with samples between cells to none: "no cell has data")."""
    h = org.headers()
    field = rectangle(112.40, 32.20, 200, 100)
    fid = make_field(client, h, field)
    (lon0, lat0), (lon1, lat1) = field["coordinates"][0][0], field["coordinates"][0][2]
    csv = "sample_id,lon,lat,n_mg_kg\n" + "".join(
        f"S{i},{lon0 + (lon1 - lon0) * f:.7f},{(lat0 + lat1) / 2:.7f},{80 + 20 * i}\n"
        for i, f in enumerate((0.27, 0.73))
    )
    r = client.post(
        f"{API}/fields/{fid}/soil-samples", headers=h, files={"file": ("s.csv", csv, "text/csv")}
    )
    assert r.status_code == 201, r.text
    plan = make_plan(client, h, fid)
    assert plan["params"]["headland_passes"] == DEFAULT_HEADLAND_PASSES
    r = client.post(
        f"{API}/plans/{plan['id']}/prescriptions",
        headers=h,
        json={"model": "nutrient_balance", "params": NB},
    )
    assert r.status_code == 201, r.text
    rx = r.json()
    assert rx["interpolation"] == DEFAULT_METHOD
    assert rx["summary"]["interpolation"]["method"] == "idw"
    # cell_mean left all but the two cells holding a sample without data (~1,700 no-data cells)
    assert rx["stats"]["no_data_count"] == 0


def test_background_prescriptions_use_the_same_default() -> None:
    """The queued path (``?background=true``, run by ``fieldrx worker``) builds through
    ``create_from_request``, which read the body with its own literal ``"cell_mean"``
    fallback after the API's default moved to ``idw`` (found at merge)."""
    import fieldrx.services.prescriptions.create as rx_service

    src = inspect.getsource(rx_service.create_from_request)
    assert '"interpolation", DEFAULT_METHOD' in src
    assert '"cell_mean"' not in src
