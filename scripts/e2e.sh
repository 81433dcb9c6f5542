#!/usr/bin/env bash
# Run the browser end-to-end tests against a real server on a throw-away database.
set -uo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
DB="fieldrx_e2e_$$"
PORT=${E2E_PORT:-8765}
export DATABASE_URL="postgresql+psycopg://postgres@127.0.0.1:5432/$DB"
export FIELDRX_URL="http://127.0.0.1:$PORT"
export FIELDRX_EMAIL=agronomist@demo.fieldrx.org FIELDRX_PASSWORD=fieldrx-demo
export PATH="$ROOT/.venv/bin:$PATH"
# this checkout's code, whichever checkout the venv's editable install points at
export PYTHONPATH="$ROOT/backend:$ROOT/edge_agent${PYTHONPATH:+:$PYTHONPATH}"
# a machine silent this long is "offline" (the fleet test waits for the push)
export FIELDRX_HEARTBEAT_TIMEOUT_S=${FIELDRX_HEARTBEAT_TIMEOUT_S:-10}
mkdir -p .run tests/e2e/artifacts
python - <<'PY'
from fieldrx.db.bootstrap import ensure_database
ensure_database()
PY
fieldrx migrate >/dev/null && fieldrx demo >/dev/null || exit 1
fieldrx serve --port "$PORT" --quiet >.run/e2e-server.log 2>&1 &
SERVER=$!
WORKER=""
if fieldrx worker --help >/dev/null 2>&1; then
  # a throw-away worker: its own group, and no session left behind on the broker
  FIELDRX_WORKER_SESSION_EXPIRY_S=0 fieldrx worker --group "e2e-$$" >.run/e2e-worker.log 2>&1 &
  WORKER=$!
fi
cleanup() {
  kill $SERVER ${WORKER:+$WORKER} 2>/dev/null
  wait 2>/dev/null
  python -c "from fieldrx.db.bootstrap import drop_database; import os; drop_database(os.environ['DATABASE_URL'])"
}
trap cleanup EXIT
# readiness, not a fixed wait: the server's start takes minutes on a loaded machine
for _ in $(seq 1 600); do curl -sf "$FIELDRX_URL/api/v1/health" >/dev/null && break; sleep 0.5; done
# the spec files given (default: all of them)
node --test --test-concurrency=1 "${@:-tests/e2e/}"
