#!/usr/bin/env bash
# Coefficients over temperature under load (issue 45 item 7): wrk at CONNS
# connections (64) for LEG seconds (10) a leg, on SQLite, against one
# release build (default target/release/accelcal), beside the plain
# routes they extend:
#
#   compensate          POST /v1/sensors/PLAIN/compensate, 100 outputs, a
#                       calibration without a temperature model;
#   compensate@33       POST /v1/sensors/MEMS-TC-7/compensate, the same 100
#                       outputs at one temperature (examples/thermal-chamber.json
#                       stored as a model);
#   compensate@100T     the same with one temperature per output (100);
#   coefficients        GET  /v1/sensors/PLAIN/coefficients (kept rendered);
#   coefficients@33     GET  /v1/sensors/MEMS-TC-7/coefficients?temperature_c=33;
#   identify            POST /v1/identify with the paper's Table 1;
#   fit                 POST /v1/identify/thermal with examples/thermal-chamber.json
#                       (40 runs, five set points);
#   fit-triad           POST /v1/identify/thermal/triad with
#                       examples/thermal-triad.json (50 six-face runs);
#   triad@33            POST /v1/sensors/IMU-TC-3/compensate, 100 triples at
#                       33 °C (examples/thermal-triad.json stored as a
#                       triad's model; builds that store one);
#   triad-coefficients@33  GET /v1/sensors/IMU-TC-3/coefficients?temperature_c=33.
#
# Prints a Markdown table (req/s, p99 ms) for BENCHMARKS.md; every answer
# must be a 2xx. Measures, never judges.
# Usage: benches/thermal.sh [path/to/accelcal]
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$(realpath "${1:-target/release/accelcal}")
CONNS=${CONNS:-64}
LEG=${LEG:-10}
command -v wrk >/dev/null || { echo "wrk is not installed (apt-get install wrk)" >&2; exit 1; }
WORK=$(mktemp -d)
export ACCELCAL_ADMIN_TOKEN="$(head -c 32 /dev/urandom | base64)"
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
"$BIN" serve --listen 127.0.0.1:$PORT --database "$WORK/thermal.db" >"$WORK/server.log" 2>&1 &
PID=$!
trap 'kill $PID 2>/dev/null; wait 2>/dev/null; rm -rf "$WORK"' EXIT
for _ in $(seq 200); do curl -sf "localhost:$PORT/readyz" >/dev/null && break; sleep 0.1; done
post() { curl -sf -o /dev/null -X POST "localhost:$PORT$1" -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" -H 'Content-Type: application/json' --data-binary "@$2"; }
python3 - "$WORK" <<'PY'
import json, sys
w = sys.argv[1]
b = json.load(open("examples/paper-table1.json")); b["sensor_id"] = "PLAIN"
json.dump(b, open(f"{w}/plain.json", "w"))
outputs = [-1.216 + 0.024 * k for k in range(100)]
json.dump({"outputs": outputs}, open(f"{w}/compensate.json", "w"))
json.dump({"outputs": outputs, "temperature_c": 33.0}, open(f"{w}/at33.json", "w"))
json.dump({"outputs": outputs, "temperature_c": [-19 + 0.78 * k for k in range(100)]}, open(f"{w}/at100.json", "w"))
triples = [[0.3 + 0.01 * k, -0.1, 9.7 - 0.02 * k] for k in range(100)]
json.dump({"outputs": triples, "temperature_c": 33.0}, open(f"{w}/triad33.json", "w"))
PY
post /v1/calibrations "$WORK/plain.json"
post /v1/calibrations/thermal examples/thermal-chamber.json
TRIAD=""
if post /v1/calibrations/thermal/triad examples/thermal-triad.json; then TRIAD=1; fi
cat >"$WORK/leg.lua" <<'LUA'
function init(args)
  wrk.headers["Authorization"] = "Bearer " .. os.getenv("ACCELCAL_ADMIN_TOKEN")
  local path = os.getenv("BODY")
  if path ~= "" then
    local f = io.open(path); wrk.body = f:read("*a"); f:close()
    wrk.method = "POST"; wrk.headers["Content-Type"] = "application/json"
  end
end
LUA
leg() { # NAME PATH BODY-FILE
  local out
  out=$(BODY=$3 wrk -t2 -c"$CONNS" -d"${LEG}"s --latency -s "$WORK/leg.lua" "http://127.0.0.1:$PORT$2")
  if grep -q "Non-2xx\|Socket errors" <<<"$out"; then echo "$out" >&2; exit 1; fi
  local rps p99
  rps=$(awk '/^Requests\/sec/ {print $2}' <<<"$out")
  p99=$(awk '$1 == "99%" { v = $2; if (v ~ /us$/) { sub(/us/, "", v); v /= 1000 } else if (v ~ /ms$/) { sub(/ms/, "", v) } else if (v ~ /s$/) { sub(/s/, "", v); v *= 1000 } print v }' <<<"$out")
  printf '| %s | `%s` | %.0f | %s |\n' "$1" "$2" "$rps" "$p99"
}
echo "| leg | route | req/s | p99 ms |"
echo "|---|---|---|---|"
leg compensate /v1/sensors/PLAIN/compensate "$WORK/compensate.json"
leg compensate@33 /v1/sensors/MEMS-TC-7/compensate "$WORK/at33.json"
leg compensate@100T /v1/sensors/MEMS-TC-7/compensate "$WORK/at100.json"
leg coefficients /v1/sensors/PLAIN/coefficients ""
leg coefficients@33 "/v1/sensors/MEMS-TC-7/coefficients?temperature_c=33" ""
leg identify /v1/identify examples/paper-table1.json
leg fit /v1/identify/thermal examples/thermal-chamber.json
leg fit-triad /v1/identify/thermal/triad examples/thermal-triad.json
if [ -n "$TRIAD" ]; then
  leg triad@33 /v1/sensors/IMU-TC-3/compensate "$WORK/triad33.json"
  leg triad-coefficients@33 "/v1/sensors/IMU-TC-3/coefficients?temperature_c=33" ""
fi
