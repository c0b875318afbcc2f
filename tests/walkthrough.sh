#!/usr/bin/env bash
# The README walkthrough, run for real: start the service, submit the paper's
# six tests with curl, read back and check the fused coefficients.
# Usage: tests/walkthrough.sh [path/to/accelcal]   (default target/debug/accelcal)
set -euo pipefail
BIN=$(realpath "${1:-$(dirname "$0")/../target/debug/accelcal}")
cd "$(dirname "$0")/.."
WORK=$(mktemp -d)
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
BASE=http://127.0.0.1:$PORT
export ACCELCAL_ADMIN_TOKEN=walkthrough-admin-token-0123
"$BIN" serve --listen 127.0.0.1:$PORT --database "$WORK/accelcal.db" >"$WORK/out.log" 2>"$WORK/err.log" &
PID=$!
trap 'kill $PID 2>/dev/null; wait $PID 2>/dev/null; rm -rf "$WORK"' EXIT
for _ in $(seq 50); do curl -sf $BASE/healthz >/dev/null && break; sleep 0.1; done

fail() { echo "walkthrough: $*" >&2; cat "$WORK/err.log" >&2; exit 1; }
json() { python3 -c "import json,sys; d=json.load(open('$1')); print($2)"; }

# --- README: a station token -------------------------------------------------
curl -sf -X POST $BASE/v1/tokens -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" \
  -H 'Content-Type: application/json' -d '{"role": "station", "station_id": "LAB-1"}' >"$WORK/token.json"
STATION=$(json "$WORK/token.json" "d['token']")

# --- README: submit the paper's six tests -------------------------------------
code=$(curl -s -o "$WORK/created.json" -w '%{http_code}' -X POST $BASE/v1/calibrations \
  -H "Authorization: Bearer $STATION" -H 'Content-Type: application/json' \
  -H 'Idempotency-Key: paper-2005-table-1' --data-binary @examples/paper-table1.json)
[ "$code" = 201 ] || fail "submit answered $code: $(cat "$WORK/created.json")"
ID=$(json "$WORK/created.json" "d['id']")
[ "$(json "$WORK/created.json" "d['station_id']")" = LAB-1 ] || fail "station not recorded"

# A retry with the same key returns the same calibration and stores nothing.
curl -sf -X POST $BASE/v1/calibrations -H "Authorization: Bearer $STATION" \
  -H 'Content-Type: application/json' -H 'Idempotency-Key: paper-2005-table-1' \
  --data-binary @examples/paper-table1.json >"$WORK/retry.json"
[ "$(json "$WORK/retry.json" "d['id']")" = "$ID" ] || fail "retry created a new calibration"

# --- README: read back the fused coefficients ---------------------------------
curl -sf $BASE/v1/sensors/PAPER-2005/coefficients -H "Authorization: Bearer $STATION" >"$WORK/coef.json"
python3 - "$WORK/coef.json" "$WORK/created.json" "$ID" <<'PY' || fail "coefficients differ from the paper"
import json, sys
coef, created, cid = json.load(open(sys.argv[1])), json.load(open(sys.argv[2])), sys.argv[3]
assert coef["calibration_id"] == cid, coef
assert abs(coef["coefficients"]["kp"] - 0.0062738448) < 1e-9, coef   # fused alpha, NOTES section 5
assert abs(created["mean"]["coefficients"]["kp"] - 0.0062108047) < 1e-9, created["mean"]
alphas = [r["coefficients"]["kp"] for r in created["runs"]]
table2 = [0.006091826, 0.006149912, 0.006163094, 0.006287309, 0.006297850, 0.006274837]
assert all(abs(a - b) < 1e-9 for a, b in zip(alphas, table2)), alphas
PY

# The submission comes back byte for byte.
curl -sf $BASE/v1/calibrations/$ID/submission -H "Authorization: Bearer $STATION" >"$WORK/sub.json"
cmp -s "$WORK/sub.json" examples/paper-table1.json || fail "submission not returned byte for byte"

# --- README: compensate raw outputs -------------------------------------------
curl -sf -X POST $BASE/v1/sensors/PAPER-2005/compensate -H "Authorization: Bearer $STATION" \
  -H 'Content-Type: application/json' -d '{"outputs": [-1.2167, 0.0055, 1.2154], "a_p": [0, 1, 0]}' >"$WORK/comp.json"
python3 -c "
import json; a=json.load(open('$WORK/comp.json'))['a_i']
assert abs(a[0]-1)<1e-3 and abs(a[1])<1e-3 and abs(a[2]+1)<1e-3, a" || fail "compensation"

# --- README: a bad submission is a precise 422 --------------------------------
code=$(curl -s -o "$WORK/bad.json" -w '%{http_code}' -X POST $BASE/v1/calibrations \
  -H "Authorization: Bearer $STATION" -H 'Content-Type: application/json' \
  -d '{"sensor_id": "ACC-1", "positions": [{"angle_deg": 0}], "runs": [{"readings": [[1.0]]}], "batchs": 2}')
[ "$code" = 422 ] || fail "bad submission answered $code"
[ "$(json "$WORK/bad.json" "d['errors'][0]['pointer']")" = /batchs ] || fail "422 does not point at /batchs"

# --- README: the CSV layout ---------------------------------------------------
{ printf '# sensor_id: PAPER-CSV\n# model: k0 ki kp\n'; cat core/tests/data/table1.csv; } >"$WORK/paper.csv"
code=$(curl -s -o "$WORK/csv.json" -w '%{http_code}' -X POST $BASE/v1/calibrations \
  -H "Authorization: Bearer $STATION" -H 'Content-Type: text/csv' --data-binary @"$WORK/paper.csv")
[ "$code" = 201 ] || fail "CSV submit answered $code: $(cat "$WORK/csv.json")"

# --- README: accelcal submit retries safely -----------------------------------
"$BIN" submit examples/paper-table1.json --url $BASE --token "$STATION" >"$WORK/cli.json"
[ "$(json "$WORK/cli.json" "d['sensor_id']")" = PAPER-2005 ] || fail "accelcal submit"
"$BIN" submit examples/paper-table1.json --url $BASE --token "$STATION" >"$WORK/cli2.json"
[ "$(json "$WORK/cli2.json" "d['id']")" = "$(json "$WORK/cli.json" "d['id']")" ] || fail "accelcal submit twice stored twice"
COUNT=$(curl -sf $BASE/v1/sensors/PAPER-2005 -H "Authorization: Bearer $STATION" | python3 -c 'import json,sys; print(json.load(sys.stdin)["calibration_count"])')
[ "$COUNT" = 2 ] || fail "expected 2 calibrations of PAPER-2005, found $COUNT"

# --- graceful stop ------------------------------------------------------------
kill -TERM $PID
wait $PID || fail "server did not exit 0 on SIGTERM"
trap 'rm -rf "$WORK"' EXIT
echo "walkthrough: ok"
