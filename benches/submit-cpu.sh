#!/usr/bin/env bash
# CPU per durable submission, the server's and (on PostgreSQL) the
# database's: BIN serves a fresh database, wrk submits the paper's Table 1
# at 64 connections (the Lua of benches/writes.sh) to SENSORS sensors (1:
# one hot sensor; 1000: a fleet) for 3 s of warm-up and an 8 s window, in
# which the server's user + system time (/proc/PID/stat) and that of every
# process of the postgres user (PostgreSQL's backends, WAL writer,
# checkpointer…) are divided by the submissions answered. Measures, never
# judges; run builds alternately, several times each (a shared machine
# drifts by tens of per cent between runs of one build).
# Usage: benches/submit-cpu.sh BIN sqlite|postgres [SENSORS]
#   PG_URL: a PostgreSQL server with trust auth (postgres://postgres@127.0.0.1:5432).
#   PERF=FILE: perf record -F 499 the server in the window, its call graph by
#   frame pointers (CALLGRAPH=dwarf,16384 for a build without them).
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$(realpath "$1"); ENGINE=$2; SENSORS=${3:-1000}
PG=${PG_URL:-postgres://postgres@127.0.0.1:5432}
W=$(mktemp -d)
export ACCELCAL_ADMIN_TOKEN="$(head -c 32 /dev/urandom | base64)"
port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
PORT=$(port); MPORT=$(port)
if [ "$ENGINE" = postgres ]; then
  db=submit_cpu_$$; psql "$PG/test" -qc "CREATE DATABASE $db"; DB=$PG/$db
else DB=$W/cpu.db; fi
"$BIN" serve --listen 127.0.0.1:$PORT --metrics-listen 127.0.0.1:$MPORT --database "$DB" >"$W/log" 2>&1 &
PID=$!
cleanup() {
  kill $PID 2>/dev/null || true; wait $PID 2>/dev/null || true
  [ "$ENGINE" = postgres ] && psql "$PG/test" -qc "DROP DATABASE IF EXISTS $db WITH (FORCE)"
  rm -rf "$W"
}
trap cleanup EXIT
for _ in $(seq 200); do curl -sf "localhost:$PORT/readyz" >/dev/null && break; sleep 0.1; done
# The submission leg's Lua and body, as benches/writes.sh writes them.
sed -n '/^cat >"$WORK\/submit.lua" <<.LUA.$/,/^LUA$/p' benches/writes.sh | sed '1d;$d' >"$W/submit.lua"
python3 - "$W/template.json" <<'PY'
import json, sys
b = json.load(open("examples/paper-table1.json"))
b["sensor_id"] = "@SENSOR@"; b["performed_at"] = "@AT@"
open(sys.argv[1], "w").write(json.dumps(b))
PY
cpu() { awk '{print $14 + $15}' "/proc/$1/stat" 2>/dev/null || echo 0; }
database() { local s=0; for p in $(pgrep -u postgres || true); do s=$((s + $(cpu "$p"))); done; echo $s; }
TEMPLATE=$W/template.json SENSORS=$SENSORS PREFIX=S- OFFSET=$((RANDOM * 1000)) STRIDE=2 FIRST=0 \
  wrk -t2 -c64 -d14s -s "$W/submit.lua" "http://127.0.0.1:$PORT/" >"$W/wrk" &
WRK=$!
sleep 3
stored() { curl -s "localhost:$MPORT/metrics" | awk '/^accelcal_submissions_total.*outcome="stored"/ {s += $2} END {print s + 0}'; }
t0=$(cpu $PID); g0=$(database); n0=$(stored)
if [ -n "${PERF:-}" ]; then perf record -q -F 499 --call-graph ${CALLGRAPH:-fp} -p $PID -o "$PERF" -- sleep 8 >/dev/null 2>&1
else sleep 8; fi
t1=$(cpu $PID); g1=$(database); n1=$(stored)
wait $WRK
if grep -q "Non-2xx\|Socket errors" "$W/wrk"; then cat "$W/wrk" >&2; exit 1; fi
python3 - "$(basename "$BIN")" "$ENGINE" "$SENSORS" $((t1 - t0)) $((g1 - g0)) $((n1 - n0)) "$(getconf CLK_TCK)" <<'PY'
import sys
name, engine, sensors, server, db, n, tick = sys.argv[1:]
n = int(n); tick = int(tick)
if n <= 0:
    sys.exit("no submission counted in the window")
us = lambda ticks: int(ticks) * 1e6 / tick / n
line = f"{name} {engine} {sensors} sensors: {n / 8:.0f} submissions/s, server {us(server):.0f} us"
if engine == "postgres":
    line += f", postgres {us(db):.0f} us, together {us(server) + us(db):.0f} us"
print(line + " per submission")
PY
