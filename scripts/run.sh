#!/usr/bin/env bash
# Set up (if needed) and run the FieldRx platform with demo data on http://127.0.0.1:8000.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
# The demo data is loaded once per database (idempotent, but its Python start costs seconds).
DB_URL=${DATABASE_URL:-postgresql+psycopg://postgres@127.0.0.1:5432/fieldrx}
HAS_DEMO=$(psql -qtA "${DB_URL/+psycopg/}" \
  -c "SELECT count(*) FROM organisations WHERE name = 'Demo Farms Co.'" 2>/dev/null || true)
if [[ $HAS_DEMO != 1 ]]; then
  .venv/bin/fieldrx demo >/dev/null
fi
HOST=${FIELDRX_HOST:-127.0.0.1}
PORT=${FIELDRX_PORT:-8000}
mkdir -p .run
WORKER_PID=""
if .venv/bin/fieldrx worker --help >/dev/null 2>&1; then
  # MQTT telemetry ingest and background tasks (plans, prescriptions, imagery ingest)
  .venv/bin/fieldrx worker --role all >.run/worker.log 2>&1 &
  WORKER_PID=$!
fi
cleanup() { [[ -n "$WORKER_PID" ]] && kill "$WORKER_PID" 2>/dev/null || true; }
trap cleanup EXIT INT TERM
cat <<MSG

  FieldRx is starting on  http://$HOST:$PORT
  API docs:               http://$HOST:$PORT/docs
  Demo sign-in:           agronomist@demo.fieldrx.org / fieldrx-demo
                          (also admin@demo.fieldrx.org and viewer@demo.fieldrx.org, same password)

MSG
.venv/bin/fieldrx serve --host "$HOST" --port "$PORT"
