#!/usr/bin/env bash
# The checks that keep the code easy to change, quick enough for the edit loop
# (`make check`; also the first step of `make test`):
#   ruff     lint, McCabe complexity <= 15, at most 8 arguments (ruff.toml)
#   ticket   comments say why, not which issue of a tracker (which is not in the repository)
#   vulture  no dead code (framework entry points listed in vulture_whitelist.py)
#   mypy     zero errors in backend/ and edge_agent/, strict on the pure packages (mypy.ini)
#   pytest   the quick unit tests of the pure modules (make test runs every test)
# Usage: scripts/check.sh [--static]   (--static: without the unit tests of pure modules)
set -uo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
export PATH="$ROOT/.venv/bin:$PATH"
FAILED=()
step() { printf '\n\033[1;34m== %s ==\033[0m\n' "$1"; }

step "ruff (lint, complexity, argument count)"
ruff check backend edge_agent tests bench || FAILED+=(ruff)

step "comments say why, not which ticket"
# "issue N", "Issue #N", "issues N and M" in any tracked source, comment or docstring
if git grep -nIiE '\bissues? #?[0-9]+' -- backend edge_agent tests bench scripts frontend/src \
    migrations deploy Makefile; then
  echo 'The lines above cite a tracker issue; say why instead (the tracker is not in the repository).'
  FAILED+=(ticket-comments)
fi

step "vulture (dead code)"
# tests and benches count as users of what they call; only shipped code is reported.
# Route handlers, validators and fixtures are called by their framework's decorator.
DECORATORS="@router.*,@app.*,@*.validator,@field_validator,@model_validator,@field_serializer"
DECORATORS+=",@model_serializer,@computed_field,@*.on_event,@*.exception_handler,@*.middleware"
DECORATORS+=",@*.task,@*.periodic,@*.listens_for,@validates,@*.setter,@pytest.fixture"
# a registry entry (an export format, a task kind) is used through its registry
DECORATORS+=",@*.register"
# (vulture's own exit status also counts findings in tests/ and bench/: the grep decides)
if { vulture backend/fieldrx edge_agent/fieldrx_edge tests bench vulture_whitelist.py \
    --min-confidence 60 --ignore-decorators "$DECORATORS" || true; } \
    | grep -E '^(backend|edge_agent)/'; then
  echo 'Dead code above: delete it (or, for a framework entry point, list it in vulture_whitelist.py).'
  FAILED+=(vulture)
fi

step "mypy (mypy.ini)"
mypy --no-error-summary || FAILED+=(mypy)

if [[ "${1:-}" != "--static" ]]; then
  step "unit tests of the pure modules (pytest --pure, not slow)"
  # the pure packages' quick tests (geometry, agronomy, control, docs, layout); the slow ones
  # (property sweeps over many fields, CLI subprocesses) and the rest are make test's
  # (the edge's controllers and what they steer: control, plants, depth, estimate)
  pytest -q -p no:cacheprovider --pure -n 0 -m "not slow" \
    tests/geo tests/agronomy tests/edge/control tests/edge/plants tests/edge/test_plants.py \
    tests/edge/test_depth.py tests/edge/test_estimate.py tests/edge/test_control_properties.py \
    tests/test_docs.py tests/test_layout.py || FAILED+=(unit)
fi

if [[ ${#FAILED[@]} -gt 0 ]]; then
  echo "FAILED: ${FAILED[*]}"
  exit 1
fi
echo "all checks passed"
