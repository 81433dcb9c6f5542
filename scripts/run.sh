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
# The server first, the worker once the server answers: both import the same heavy
# modules, and on two cores starting them together doubles the time to the first answer.
.venv/bin/fieldrx serve --host "$HOST" --port "$PORT" &
SERVER_PID=$!
WORKER_PID=""
cleanup() {
  kill $SERVER_PID ${WORKER_PID:+$WORKER_PID} 2>/dev/null || true
  wait 2>/dev/null || true
}
trap cleanup EXIT INT TERM
until curl -sf "http://$HOST:$PORT/api/v1/health" >/dev/null; do
  kill -0 $SERVER_PID 2>/dev/null || { echo "the server did not start (see above)" >&2; exit 1; }
  sleep 0.2
done
# MQTT telemetry ingest and background tasks (plans, prescriptions, imagery ingest)
.venv/bin/fieldrx worker --role all >.run/worker.log 2>&1 &
WORKER_PID=$!
cat <<MSG

  FieldRx is running on   http://$HOST:$PORT
  API docs:               http://$HOST:$PORT/docs
  Demo sign-in:           agronomist@demo.fieldrx.org / fieldrx-demo
                          (also admin@demo.fieldrx.org and viewer@demo.fieldrx.org, same password)
  Background worker log:  .run/worker.log

MSG
wait $SERVER_PID
