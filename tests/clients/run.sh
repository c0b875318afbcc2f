#!/usr/bin/env bash
# Clients generated from openapi.yaml, as integrators generate them, used
# against a running accelcal: TypeScript with openapi-typescript (+
# openapi-fetch) and with @hey-api/openapi-ts, both compiled with
# `tsc --strict`, and Python with openapi-python-client. Each generator must
# print no warning; each program submits JSON and CSV, reads coefficients,
# history, stability and the stored submission, and handles a 422 problem.
# Usage: tests/clients/run.sh [path/to/accelcal] [sqlite|postgres]
# Needs node/npm and, on PATH, the packages of tests/clients/requirements.txt
# (.ci/run installs them).
set -euo pipefail
BIN=$(realpath "${1:-$(dirname "$0")/../../target/debug/accelcal}")
ENGINE=${2:-sqlite}
cd "$(dirname "$0")/../.."
HERE=tests/clients
[ -d $HERE/node_modules/openapi-typescript ] || npm ci --prefix $HERE --no-audit --no-fund --silent
WORK=$(mktemp -d)
fail() { echo "clients: $*" >&2; exit 1; }
# Generation: every generator's output is shown, and any warning fails.
quiet() { # command… — runs it; fails when it printed a warning
  "$@" >"$WORK/gen.log" 2>&1 || { cat "$WORK/gen.log" >&2; fail "$1 failed"; }
  if grep -qiE 'warn' "$WORK/gen.log"; then cat "$WORK/gen.log" >&2; fail "$1 printed a warning"; fi
}
"$BIN" openapi >"$WORK/openapi.yaml"
rm -rf $HERE/gen $HERE/build
mkdir -p $HERE/gen/typed
quiet $HERE/node_modules/.bin/openapi-typescript "$WORK/openapi.yaml" -o $HERE/gen/typed/schema.d.ts
quiet $HERE/node_modules/.bin/openapi-ts -i "$WORK/openapi.yaml" -o $HERE/gen/hey
quiet openapi-python-client generate --path "$WORK/openapi.yaml" --output-path "$WORK/py" \
  --config $HERE/python/config.yaml
$HERE/node_modules/.bin/tsc -p $HERE || fail "tsc --strict refused a client program"

PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
export ACCELCAL_ADMIN_TOKEN="$(head -c 32 /dev/urandom | base64)"
case $ENGINE in
  sqlite) DATABASE=$WORK/clients.db; DROP=: ;;
  postgres)
    ADMIN_URL=${ACCELCAL_TEST_POSTGRES_URL:-postgres://postgres@127.0.0.1:5432/test}
    NAME=accelcal_clients_$$
    psql -q "$ADMIN_URL" -c "CREATE DATABASE $NAME" >/dev/null
    DATABASE=${ADMIN_URL%/*}/$NAME
    DROP="psql -q $ADMIN_URL -c 'DROP DATABASE IF EXISTS $NAME WITH (FORCE)'" ;;
  *) fail "engine must be sqlite or postgres" ;;
esac
"$BIN" serve --listen 127.0.0.1:$PORT --database "$DATABASE" >"$WORK/server.log" 2>&1 &
PID=$!
trap 'kill $PID 2>/dev/null; wait $PID 2>/dev/null; eval "$DROP" >/dev/null 2>&1; rm -rf "$WORK"' EXIT
for _ in $(seq 100); do curl -sf http://127.0.0.1:$PORT/readyz >/dev/null && break; sleep 0.1; done
export ACCELCAL_URL=http://127.0.0.1:$PORT
ACCELCAL_TOKEN=$(curl -sf -X POST $ACCELCAL_URL/v1/tokens -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" \
  -H 'Content-Type: application/json' -d '{"role": "station"}' \
  | python3 -c 'import json, sys; print(json.load(sys.stdin)["token"])')
export ACCELCAL_TOKEN
node $HERE/build/ts/typed.js
node $HERE/build/ts/hey.js
PYTHONPATH="$WORK/py" python3 $HERE/python/client_test.py
if grep -q 'status=5[0-9][0-9]' "$WORK/server.log"; then fail "the server answered 5xx"; fi
echo "clients ($ENGINE): ok"
