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
# The webhook receiver example is compiled with them (and run below).
cp examples/webhooks/receiver.ts $HERE/gen/receiver.ts
$HERE/node_modules/.bin/tsc -p $HERE || fail "tsc --strict refused a client program"

. tests/server.sh
export ACCELCAL_WEBHOOK_ALLOW_PRIVATE=true # the example receiver below, on loopback
start_server "$ENGINE" clients "$WORK/server.log" "$WORK/server.log"
export ACCELCAL_URL=$BASE
ACCELCAL_TOKEN=$(curl -sf -X POST $ACCELCAL_URL/v1/tokens -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" \
  -H 'Content-Type: application/json' -d '{"role": "station"}' \
  | python3 -c 'import json, sys; print(json.load(sys.stdin)["token"])')
export ACCELCAL_TOKEN
node $HERE/build/ts/typed.js
node $HERE/build/ts/hey.js
PYTHONPATH="$WORK/py" python3 $HERE/python/client_test.py
# The TypeScript webhook receiver (examples/webhooks/receiver.ts) verifies
# a real delivery with the standardwebhooks package and prints it.
HOOK_PORT=$(free_port)
SECRET=$(curl -sf -X PUT $BASE/v1/webhooks/ts-example -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" \
  -H 'Content-Type: application/json' -d "{\"url\": \"http://127.0.0.1:$HOOK_PORT/\", \"sensors\": [\"TS-HOOK\"]}" \
  | python3 -c 'import json, sys; print(json.load(sys.stdin)["secret"])')
ACCELCAL_WEBHOOK_SECRET=$SECRET node $HERE/build/gen/receiver.js "$HOOK_PORT" >"$WORK/hook.out" 2>&1 &
HOOK=$!
sleep 0.5
python3 -c 'import json; b = json.load(open("examples/paper-table1.json")); b["sensor_id"] = "TS-HOOK"; print(json.dumps(b))' \
  | curl -sf -o /dev/null -X POST $BASE/v1/calibrations -H "Authorization: Bearer $ACCELCAL_TOKEN" \
      -H 'Content-Type: application/json' --data-binary @-
for _ in $(seq 100); do grep -q '"type":"calibration.stored","sensor":"TS-HOOK"' "$WORK/hook.out" && break; sleep 0.1; done
kill $HOOK
grep -q '"type":"calibration.stored","sensor":"TS-HOOK"' "$WORK/hook.out" \
  || { cat "$WORK/hook.out" >&2; fail "the TypeScript receiver did not verify the delivery"; }
if grep -q 'status=5[0-9][0-9]' "$WORK/server.log"; then fail "the server answered 5xx"; fi
echo "clients ($ENGINE): ok"
