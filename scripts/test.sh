#!/usr/bin/env bash
# Set up (if needed) and run every FieldRx test: the checks of scripts/check.sh (lint,
# types, dead code), Python tests against the real PostGIS and Mosquitto, frontend unit
# tests, and browser end-to-end tests in Chromium.
set -uo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
scripts/setup.sh --test || exit 1
export PATH="$ROOT/.venv/bin:$PATH"
FAILED=()
step() { printf '\n\033[1;34m== %s ==\033[0m\n' "$1"; }

scripts/check.sh --static || FAILED+=(check)

# The browser tests spend most of their time waiting on a simulated job driven in real time
# (measured: 64 s of CPU in 7 min 53 s of wall time), so they run beside pytest, each on its
# own database, server and port; their output is shown when they end.
E2E_PID=""
E2E_LOG=.run/e2e-tests.log
if compgen -G "tests/e2e/*.test.mjs" >/dev/null; then
  mkdir -p .run
  scripts/e2e.sh >"$E2E_LOG" 2>&1 &
  E2E_PID=$!
  # an interrupted run takes its browser tests (and their server) with it
  trap '[[ -n "$E2E_PID" ]] && kill "$E2E_PID" 2>/dev/null' EXIT
fi

step "pytest"
# Parallel workers (pytest-xdist), each with its own throw-away database and broker
# (tests/conftest.py). Many tests wait on servers, workers and brokers they start, so one
# worker more than cores keeps the CPUs busy: on 2 cores, 3 workers ran pytest in
# 9 min 54 s beside the browser tests (2 workers: 12 min 11 s, with another job running).
WORKERS=${FIELDRX_TEST_WORKERS:-$(( $(nproc) + 1 ))}
pytest -q -p no:cacheprovider -n "$WORKERS" --durations=15 || FAILED+=(pytest)

if [[ -f frontend/package.json ]]; then
  step "frontend unit tests (vitest)"
  (cd frontend && npm test --silent) || FAILED+=(vitest)
fi

if [[ -n "$E2E_PID" ]]; then
  step "browser end-to-end tests (playwright-core + chromium; ran beside pytest)"
  wait "$E2E_PID" || FAILED+=(e2e)
  cat "$E2E_LOG"
fi

if [[ ${#FAILED[@]} -gt 0 ]]; then
  echo "FAILED: ${FAILED[*]}"
  exit 1
fi
echo "all test suites passed"
