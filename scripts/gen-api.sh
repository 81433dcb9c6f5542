#!/usr/bin/env bash
# Regenerate the browser's typed API client from the server's OpenAPI document (no server
# needed): frontend/src/api/openapi.json, then frontend/src/api/generated/schema.ts
# (openapi-typescript), generated/defaults.json (the models' defaults the forms start from),
# generated/import-formats.json (the import-format registry the import assistant reads) and
# generated/rate-models.json and generated/rate-units.json (the rate-model and rate-unit
# registries the prescription forms read).
# Run after changing a route, a model in backend/fieldrx/api/, an import format, a rate
# model or a rate unit;
# tests/system/test_contract.py fails while the committed files are stale.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
PY=${PYTHON:-$ROOT/.venv/bin/python}
mkdir -p frontend/src/api/generated
PYTHONPATH="$ROOT/backend:$ROOT/edge_agent${PYTHONPATH:+:$PYTHONPATH}" "$PY" -c \
  "from fieldrx.app import create_app; from fieldrx.apidocs import openapi_json; print(openapi_json(create_app()), end='')" \
  >frontend/src/api/openapi.json
PYTHONPATH="$ROOT/backend${PYTHONPATH:+:$PYTHONPATH}" "$PY" -c \
  "from fieldrx.apidocs import schema_defaults_json; print(schema_defaults_json(open('frontend/src/api/openapi.json').read()), end='')" \
  >frontend/src/api/generated/defaults.json
PYTHONPATH="$ROOT/backend${PYTHONPATH:+:$PYTHONPATH}" "$PY" -c \
  "from fieldrx.formats.import_formats import registry_json; print(registry_json(), end='')" \
  >frontend/src/api/generated/import-formats.json
PYTHONPATH="$ROOT/backend:$ROOT/edge_agent${PYTHONPATH:+:$PYTHONPATH}" "$PY" -c \
  "from fieldrx.agronomy.ratemodels.registry import registry_json; print(registry_json(), end='')" \
  >frontend/src/api/generated/rate-models.json
PYTHONPATH="$ROOT/edge_agent${PYTHONPATH:+:$PYTHONPATH}" "$PY" -c \
  "from fieldrx_edge.rateunits.registry import registry_json; print(registry_json(), end='')" \
  >frontend/src/api/generated/rate-units.json
(cd frontend && npx --no-install openapi-typescript src/api/openapi.json \
  -o src/api/generated/schema.ts --alphabetize --default-non-nullable false >/dev/null)
echo "frontend/src/api/openapi.json, generated/schema.ts, defaults.json, import-formats.json, rate-models.json and rate-units.json are current"
