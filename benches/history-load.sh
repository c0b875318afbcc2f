#!/usr/bin/env bash
# A long history's page under load on PostgreSQL (issue 48 items 3 and 4):
# per build, a fresh database whose one sensor HOT is filled by FILL
# seconds (16) of durable submissions at 64 connections (the Lua of
# benches/writes.sh: the paper's Table 1, a new performed_at each time),
# then GET /v1/sensors/HOT/calibrations?limit=20 for LEG seconds (8) at
# 64 connections after a 2 s warm-up: req/s, p99, and the CPU per page of
# accelcal and of all PostgreSQL's processes (/proc, user + system). The
# builds alternate over ROUNDS rounds (2), each round on a database of
# its own. Measures, never judges.
# Usage: benches/history-load.sh NAME=BIN NAME=BIN ...
# PG_URL: a PostgreSQL server with trust auth (postgres://postgres@127.0.0.1:5432).
set -euo pipefail
cd "$(dirname "$0")/.."
FILL=${FILL:-16}
LEG=${LEG:-8}
ROUNDS=${ROUNDS:-2}
PG=${PG_URL:-postgres://postgres@127.0.0.1:5432}
WORK=$(mktemp -d)
SERVER=
cleanup() {
  [ -n "$SERVER" ] && kill "$SERVER" 2>/dev/null || true
  psql "$PG/test" -qc "DROP DATABASE IF EXISTS history_load_bench WITH (FORCE)" >/dev/null 2>&1 || true
  rm -rf "$WORK"
}
trap cleanup EXIT
export ACCELCAL_ADMIN_TOKEN="$(head -c 32 /dev/urandom | base64)"
command -v wrk >/dev/null || { echo "wrk is not installed (apt-get install wrk)" >&2; exit 1; }
[ $# -ge 1 ] || { sed -n 2,13p "$0" >&2; exit 2; }

python3 - "$WORK/template.json" <<'PY'
import json, sys
b = json.load(open("examples/paper-table1.json"))
b["sensor_id"] = "@SENSOR@"; b["performed_at"] = "@AT@"
open(sys.argv[1], "w").write(json.dumps(b))
PY
sed -n '/^cat >"\$WORK\/submit.lua" <<.LUA.$/,/^LUA$/p' benches/writes.sh | sed '1d;$d' >"$WORK/submit.lua"
cat >"$WORK/read.lua" <<'LUA'
wrk.headers["Authorization"] = "Bearer " .. os.getenv("ACCELCAL_ADMIN_TOKEN")
LUA
# The CPU ticks of every PostgreSQL process.
pg_ticks() {
  for f in /proc/[0-9]*/stat; do read -r l <"$f" 2>/dev/null || continue
    case "$l" in *"(postgres)"*) echo "$l" ;; esac; done | awk '{ s += $14 + $15 } END { print s + 0 }'
}
tick=$(getconf CLK_TCK)
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
echo "| round | build | HOT's calibrations | history req/s | p99 | accelcal µs/page | PostgreSQL µs/page |"
echo "|---|---|---|---|---|---|---|"
for round in $(seq "$ROUNDS"); do
  for arg in "$@"; do
    name=${arg%%=*}; bin=$(realpath "${arg#*=}")
    psql "$PG/test" -qc "DROP DATABASE IF EXISTS history_load_bench WITH (FORCE)" >/dev/null 2>&1
    psql "$PG/test" -qc "CREATE DATABASE history_load_bench"
    "$bin" serve --listen 127.0.0.1:$port --database "$PG/history_load_bench" >"$WORK/$name.log" 2>&1 &
    SERVER=$!
    for _ in $(seq 200); do curl -sf "localhost:$port/readyz" >/dev/null && break; sleep 0.1; done
    TEMPLATE="$WORK/template.json" SENSORS=1 PREFIX=HOT OFFSET=1 STRIDE=2 FIRST=0 \
      wrk -t2 -c64 -d${FILL}s -s "$WORK/submit.lua" "http://127.0.0.1:$port/v1/calibrations" >/dev/null
    count=$(curl -s "localhost:$port/v1/sensors/HOT" -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" \
      | python3 -c 'import json,sys; print(json.load(sys.stdin)["calibration_count"])')
    url="http://127.0.0.1:$port/v1/sensors/HOT/calibrations?limit=20"
    wrk -t2 -c64 -d2s -s "$WORK/read.lua" "$url" >/dev/null
    p0=$(pg_ticks); a0=$(awk '{print $14 + $15}' /proc/$SERVER/stat)
    out=$(wrk -t2 -c64 -d${LEG}s --latency -s "$WORK/read.lua" "$url")
    p1=$(pg_ticks); a1=$(awk '{print $14 + $15}' /proc/$SERVER/stat)
    kill "$SERVER"; wait "$SERVER" 2>/dev/null || true; SERVER=
    if grep -q "Non-2xx\|Socket errors" <<<"$out"; then echo "$out" >&2; exit 1; fi
    n=$(awk '/requests in/ {print $1}' <<<"$out")
    rps=$(awk '/^Requests\/sec/ {print $2}' <<<"$out")
    p99=$(awk '$1 == "99%" {print $2}' <<<"$out")
    echo "| $round | $name | $count | $rps | $p99 | $(( (a1 - a0) * 1000000 / tick / n )) | $(( (p1 - p0) * 1000000 / tick / n )) |"
  done
done
