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

. tests/server.sh
start_server "$ENGINE" clients "$WORK/server.log" "$WORK/server.log"
export ACCELCAL_URL=$BASE
ACCELCAL_TOKEN=$(curl -sf -X POST $ACCELCAL_URL/v1/tokens -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" \
  -H 'Content-Type: application/json' -d '{"role": "station"}' \
  | python3 -c 'import json, sys; print(json.load(sys.stdin)["token"])')
export ACCELCAL_TOKEN
node $HERE/build/ts/typed.js
node $HERE/build/ts/hey.js
PYTHONPATH="$WORK/py" python3 $HERE/python/client_test.py
if grep -q 'status=5[0-9][0-9]' "$WORK/server.log"; then fail "the server answered 5xx"; fi
echo "clients ($ENGINE): ok"
