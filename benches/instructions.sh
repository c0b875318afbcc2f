#!/usr/bin/env bash
# Instructions the server executes per request, counted by valgrind's
# callgrind: unlike req/s or CPU time, the same binary, configuration and
# requests give the same count on a busy machine, so two builds can be
# compared where the load benchmark's legs drift by a third.
#
#   benches/instructions.sh [BIN]        # default target/release/accelcal
#
# Environment: ROUTE (coefficients | history | submit | compensate;
# default coefficients), N requests counted (default 2000), RUST_LOG
# (default warn), LOG_FORMAT (json | text, default json), METRICS=1 to run
# with --metrics-listen. Prints one Markdown row: the binary, the
# configuration and the instructions per request (all threads, the log
# writer's included). Needs valgrind and python3.
set -euo pipefail
BIN=${1:-target/release/accelcal}
ROUTE=${ROUTE:-coefficients}
N=${N:-2000}
LOG=${RUST_LOG:-warn}
FORMAT=${LOG_FORMAT:-json}
WORK=$(mktemp -d)
TOKEN="$(head -c 32 /dev/urandom | base64)"
PORT=$((20000 + RANDOM % 20000))
FLAGS=()
if [ -n "${METRICS:-}" ]; then FLAGS=(--metrics-listen 127.0.0.1:$((PORT + 1))); fi
RUST_LOG=$LOG ACCELCAL_ADMIN_TOKEN=$TOKEN valgrind --tool=callgrind --instr-atstart=no \
  --callgrind-out-file="$WORK/cg.out" "$BIN" serve --database "$WORK/a.db" \
  --listen 127.0.0.1:$PORT --log-format "$FORMAT" "${FLAGS[@]}" >"$WORK/out.log" 2>"$WORK/err.log" &
PID=$!
trap 'kill $PID 2>/dev/null; wait 2>/dev/null; [ -n "${KEEP:-}" ] || rm -rf "$WORK"' EXIT
for _ in $(seq 600); do curl -sf http://127.0.0.1:$PORT/healthz >/dev/null && break; sleep 0.1; done

python3 - "$PORT" "$TOKEN" "$ROUTE" "$N" "$PID" <<'EOF'
import datetime, http.client, json, subprocess, sys
port, token, route, n, pid = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), sys.argv[5]
paper = json.load(open("examples/paper-table1.json"))
sensor = paper["sensor_id"]
c = http.client.HTTPConnection("127.0.0.1", int(port))
auth = {"Authorization": f"Bearer {token}", "Content-Type": "application/json"}
count = [0]

def submission():
    count[0] += 1
    body = dict(paper)
    t = datetime.datetime(2024, 1, 1, tzinfo=datetime.timezone.utc) + datetime.timedelta(seconds=count[0])
    body["performed_at"] = t.strftime("%Y-%m-%dT%H:%M:%SZ")
    return json.dumps(body)

def request():
    if route == "submit":
        c.request("POST", "/v1/calibrations", submission(), auth); want = 201
    elif route == "compensate":
        outputs = {"outputs": [-1.216 + 0.024 * k for k in range(100)]}
        c.request("POST", f"/v1/sensors/{sensor}/compensate", json.dumps(outputs), auth); want = 200
    elif route == "history":
        c.request("GET", f"/v1/sensors/{sensor}/calibrations?limit=20", headers=auth); want = 200
    else:
        c.request("GET", f"/v1/sensors/{sensor}/coefficients", headers=auth); want = 200
    r = c.getresponse(); r.read()
    assert r.status == want, (r.status, route)

for _ in range(20):
    c.request("POST", "/v1/calibrations", submission(), auth)
    r = c.getresponse(); r.read(); assert r.status == 201, r.status
for _ in range(200):
    request()
subprocess.run(["callgrind_control", "-i", "on", pid], check=True, capture_output=True)
for _ in range(n):
    request()
subprocess.run(["callgrind_control", "-i", "off", pid], check=True, capture_output=True)
subprocess.run(["callgrind_control", "-d", pid], check=True, capture_output=True)
EOF
total=0
for f in "$WORK"/cg.out*; do
  t=$(awk '/^totals:/ {print $2}' "$f")
  total=$((total + ${t:-0}))
done
printf '| %s | %s | RUST_LOG=%s %s%s | %d |\n' "$(basename "$BIN")" "$ROUTE" "$LOG" "$FORMAT" \
  "${METRICS:+ metrics}" $((total / N))
