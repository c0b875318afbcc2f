#!/usr/bin/env bash
# The server's CPU per request of one route under load: starts BIN on a
# fresh SQLite database, warms up for 3 s, then runs wrk (2 threads, 64
# connections) for 6 s and divides the server's user and system time over
# the leg (/proc/PID/stat) by the requests answered. Measures, never
# judges; for comparing builds side by side, alternately.
# Usage: benches/cpu.sh BIN [ROUTE] [BODY-FILE]
#   default: POST /v1/identify/thermal examples/thermal-chamber.json
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$(realpath "$1")
ROUTE=${2:-/v1/identify/thermal}
BODY=$(realpath "${3:-examples/thermal-chamber.json}")
W=$(mktemp -d)
export ACCELCAL_ADMIN_TOKEN="$(head -c 32 /dev/urandom | base64)"
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
"$BIN" serve --listen 127.0.0.1:$PORT --database "$W/cpu.db" >"$W/log" 2>&1 &
PID=$!
trap 'kill $PID 2>/dev/null; wait 2>/dev/null; rm -rf "$W"' EXIT
for _ in $(seq 200); do curl -sf "localhost:$PORT/readyz" >/dev/null && break; sleep 0.1; done
cat >"$W/l.lua" <<LUA
wrk.headers["Authorization"] = "Bearer " .. os.getenv("ACCELCAL_ADMIN_TOKEN")
local f = io.open("$BODY"); wrk.body = f:read("*a"); f:close()
wrk.method = "POST"; wrk.headers["Content-Type"] = "application/json"
LUA
wrk -t2 -c64 -d3s -s "$W/l.lua" "http://127.0.0.1:$PORT$ROUTE" >/dev/null
t0=$(awk '{print $14 + $15}' /proc/$PID/stat)
out=$(wrk -t2 -c64 -d6s -s "$W/l.lua" "http://127.0.0.1:$PORT$ROUTE")
t1=$(awk '{print $14 + $15}' /proc/$PID/stat)
n=$(awk '/requests in/ {print $1}' <<<"$out")
tick=$(getconf CLK_TCK)
echo "$(basename "$BIN"): $n requests, server CPU $(( (t1 - t0) * 1000 / tick )) ms, $(( (t1 - t0) * 1000000 / tick / n )) us/request"
