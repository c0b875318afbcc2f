#!/usr/bin/env bash
# The README walkthrough, run for real: start the service, submit the paper's
# six tests with curl, read back and check the fused coefficients.
# Usage: tests/walkthrough.sh [path/to/accelcal] [sqlite|postgres]
#   (defaults target/debug/accelcal, sqlite). With `postgres`, the service
#   runs on a fresh database of the server ACCELCAL_TEST_POSTGRES_URL names
#   (default postgres://postgres@127.0.0.1:5432/test), dropped afterwards.
set -euo pipefail
BIN=$(realpath "${1:-$(dirname "$0")/../target/debug/accelcal}")
ENGINE=${2:-sqlite}
cd "$(dirname "$0")/.."
WORK=$(mktemp -d)
. tests/server.sh
start_server "$ENGINE" walkthrough "$WORK/out.log" "$WORK/err.log"

fail() { echo "walkthrough: $*" >&2; cat "$WORK/err.log" >&2; exit 1; }

# --- the README's walkthrough block, run as written (SQLite, as it reads) ----
# Only what cannot run here is replaced: the release build by the binary
# under test, port 8080 by a free one.
if [ "$ENGINE" = sqlite ]; then
  README_PORT=$(free_port)
  mkdir "$WORK/readme" && ln -s "$PWD/examples" "$WORK/readme/examples"
  python3 - "$BIN" "$README_PORT" >"$WORK/readme/walkthrough.sh" <<'PY'
import re, sys
text = open("README.md").read()
block = re.search(r"Every command below runs as written.*?```sh\n(.*?)```", text, re.S).group(1)
bin_, port = sys.argv[1], sys.argv[2]
block = block.replace("cargo run --release -- serve &", f'"{bin_}" serve --listen 127.0.0.1:{port} &')
block = block.replace("cargo run --release --", f'"{bin_}"')
block = block.replace("localhost:8080", f"127.0.0.1:{port}")
print("set -euo pipefail\nexport ACCELCAL_URL=http://127.0.0.1:" + port)
print(block)
print('kill $(jobs -p) 2>/dev/null; wait')
PY
  (cd "$WORK/readme" && bash walkthrough.sh >out.txt 2>err.txt) \
    || { cat "$WORK/readme/out.txt" "$WORK/readme/err.txt" >&2; echo "walkthrough: the README's block failed" >&2; exit 1; }
  # Both submissions (Table 1 and its recalibration) show their status and Location.
  [ "$(grep -c '^HTTP/1.1 201' "$WORK/readme/out.txt")" = 2 ] || { echo "walkthrough: not every submission's 201 status line shown" >&2; exit 1; }
  [ "$(grep -ci '^location: /v1/calibrations/' "$WORK/readme/out.txt")" = 2 ] || { echo "walkthrough: not every submission's Location shown" >&2; exit 1; }
  ids=$(tail -n 2 "$WORK/readme/out.txt" | sort -u | wc -l)
  [ "$ids" = 1 ] || { echo "walkthrough: accelcal submit stored the CSV twice" >&2; exit 1; }
  echo "walkthrough: the README's block ran as written"
fi
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
python3 - "$WORK/coef.json" "$WORK/created.json" "$ID" core/tests/data/reference.json <<'PY' || fail "coefficients differ from the reference"
import json, sys
coef, created, cid = json.load(open(sys.argv[1])), json.load(open(sys.argv[2])), sys.argv[3]
ref = json.load(open(sys.argv[4]))["table1"]   # independent: core/tests/data/reference.py
def near(got, want, rel):
    assert abs(got - want) <= rel * abs(want), (got, want)
assert coef["calibration_id"] == cid, coef
for t in ("k0", "ki", "kp"):
    near(coef["coefficients"][t], ref["fused"][t], 1e-12)
    near(coef["std_errors"][t], ref["fused_std_error"][t], 1e-9)
    near(created["mean"]["coefficients"][t], ref["mean"][t], 1e-12)
    for run, want in zip(created["runs"], ref["runs"]):
        near(run["coefficients"][t], want["coefficients"][t], 1e-12)
# What the README prints: k0 -0.000682…, ki -1.216154…, kp 0.0062738449…
assert str(coef["coefficients"]["k0"]).startswith("-0.000682"), coef
assert str(coef["coefficients"]["ki"]).startswith("-1.216154"), coef
assert str(coef["coefficients"]["kp"]).startswith("0.0062738449"), coef
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
python3 - "$WORK/comp.json" "$WORK/coef.json" <<'PY' || fail "compensation"
import json, sys
a, k = json.load(open(sys.argv[1]))["a_i"], json.load(open(sys.argv[2]))["coefficients"]
# The linear model inverted by hand: a_i = (U - k0 - kp a_p) / ki.
for got, u, ap in zip(a, [-1.2167, 0.0055, 1.2154], [0, 1, 0]):
    want = (u - k["k0"] - k["kp"] * ap) / k["ki"]
    assert abs(got - want) < 1e-12, (got, want)
PY

# --- README: a bad submission is a precise 422 --------------------------------
code=$(curl -s -o "$WORK/bad.json" -w '%{http_code}' -X POST $BASE/v1/calibrations \
  -H "Authorization: Bearer $STATION" -H 'Content-Type: application/json' \
  -d '{"sensor_id": "ACC-1", "positions": [{"angle_deg": 0}], "runs": [{"readings": [[1.0]]}], "batchs": 2}')
[ "$code" = 422 ] || fail "bad submission answered $code"
[ "$(json "$WORK/bad.json" "d['errors'][0]['pointer']")" = /batchs ] || fail "422 does not point at /batchs"

# --- README: the CSV layout ---------------------------------------------------
# examples/paper-table1.csv is Table 1 with its metadata lines (sensor PAPER-CSV).
code=$(curl -s -o "$WORK/csv.json" -w '%{http_code}' -X POST $BASE/v1/calibrations \
  -H "Authorization: Bearer $STATION" -H 'Content-Type: text/csv' --data-binary @examples/paper-table1.csv)
[ "$code" = 201 ] || fail "CSV submit answered $code: $(cat "$WORK/csv.json")"

# --- README: a sensor type, a recalibration a year on --------------------------
code=$(curl -s -o "$WORK/type.json" -w '%{http_code}' -X PUT $BASE/v1/sensor-types/NAV \
  -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" -H 'Content-Type: application/json' \
  --data-binary @examples/sensor-type-nav.json)
[ "$code" = 201 ] || fail "sensor type answered $code: $(cat "$WORK/type.json")"
code=$(curl -s -o "$WORK/recal.json" -w '%{http_code}' -X POST $BASE/v1/calibrations \
  -H "Authorization: Bearer $STATION" -H 'Content-Type: application/json' \
  --data-binary @examples/paper-recalibration.json)
[ "$code" = 201 ] || fail "recalibration answered $code: $(cat "$WORK/recal.json")"
curl -sf $BASE/v1/sensors/PAPER-2005 -H "Authorization: Bearer $STATION" >"$WORK/sensor.json"
curl -sf $BASE/v1/sensors/PAPER-2005/stability -H "Authorization: Bearer $STATION" >"$WORK/stability.json"
python3 - "$WORK/recal.json" "$WORK/created.json" examples/sensor-type-nav.json "$WORK/sensor.json" "$WORK/stability.json" <<'PY' || fail "metrology"
import json, math, sys
r, first, typ, sensor, stab = (json.load(open(p)) for p in sys.argv[1:6])
# The guarded decision (ILAC-G8), re-derived from the values, U and limits.
for t, lim in typ["limits"].items():
    x, u = r["fused"]["coefficients"][t], r["uncertainty"]["terms"][t]["expanded"]
    lo, hi = lim.get("min", -math.inf), lim.get("max", math.inf)
    want = "pass" if lo + u <= x <= hi - u else ("fail" if x < lo - u or x > hi + u else "conditional")
    assert r["decision"]["terms"][t]["verdict"] == want, (t, r["decision"])
verdicts = [d["verdict"] for d in r["decision"]["terms"].values()]
worst = "fail" if "fail" in verdicts else ("conditional" if "conditional" in verdicts else "pass")
assert r["decision"]["verdict"] == worst and r["decision"]["rule"] == "guarded", r["decision"]
# The stand's gravity part of ki's budget is u·|ki| (a linear model).
ki = r["fused"]["coefficients"]["ki"]
assert abs(r["uncertainty"]["terms"]["ki"]["gravity"] - 1e-5 * abs(ki)) < 1e-15
# As found, by hand from the submitted file: the mean of every sample at a
# position minus the first calibration's fused model at that position's a.
af = r["as_found"]
assert af["previous_calibration_id"] == first["id"], af
body = json.load(open("examples/paper-recalibration.json"))
k = first["fused"]["coefficients"]
assert len(af["positions"]) == len(body["positions"]), af
for i, (pos, e) in enumerate(zip(body["positions"], af["positions"])):
    th = math.radians(pos["angle_deg"])
    a_i, a_p = -math.sin(th), math.cos(th)
    samples = [x for run in body["runs"] for x in run["readings"][i]]
    want = sum(samples) / len(samples) - (k["k0"] + k["ki"] * a_i + k["kp"] * a_p)
    assert abs(e["error_output"] - want) < 1e-12, (i, e, want)
    assert abs(e["error_g"] - want / k["ki"]) < 1e-12, (i, e)
assert af["max_abs_error_g"] == max(abs(e["error_g"]) for e in af["positions"]), af
assert r["due_at"] == "2007-08-01T00:00:00.000000Z", r["due_at"]
assert sensor["sensor_type"] == "NAV" and sensor["latest_verdict"] == r["decision"]["verdict"], sensor
# Stability over the two: the change in k0 is the drift put in.
k0 = stab["terms"]["k0"]
assert stab["calibrations"] == 2 and abs(k0["latest_change"] - 2.1e-5) < 1e-12, stab
assert k0["drift_per_year"] is None
PY

# --- README: accelcal submit retries safely -----------------------------------
# The same file again, by the CLI: its content-derived key is new, so it is
# stored once more under PAPER-CSV, then a second CLI upload is a replay.
"$BIN" submit examples/paper-table1.csv --url $BASE --token "$STATION" >"$WORK/cli.json"
[ "$(json "$WORK/cli.json" "d['sensor_id']")" = PAPER-CSV ] || fail "accelcal submit"
"$BIN" submit examples/paper-table1.csv --url $BASE --token "$STATION" >"$WORK/cli2.json"
[ "$(json "$WORK/cli2.json" "d['id']")" = "$(json "$WORK/cli.json" "d['id']")" ] || fail "accelcal submit twice stored twice"
COUNT=$(curl -sf $BASE/v1/sensors/PAPER-2005 -H "Authorization: Bearer $STATION" | python3 -c 'import json,sys; print(json.load(sys.stdin)["calibration_count"])')
[ "$COUNT" = 2 ] || fail "expected 2 calibrations of PAPER-2005 (Table 1 and its recalibration), found $COUNT"

# --- graceful stop ------------------------------------------------------------
kill -TERM $PID
wait $PID || fail "server did not exit 0 on SIGTERM"
trap 'eval "$DROP" >/dev/null 2>&1; rm -rf "$WORK"' EXIT
echo "walkthrough ($ENGINE): ok"
