#!/usr/bin/env bash
# Writes and reads under load, builds side by side (issue 48 item 4): wrk at
# CONNS connections (64), LEG seconds a leg (10), ROUNDS rounds (3) in which
# the builds alternate (in an order that rotates), on each engine of ENGINES
# (sqlite postgres). Per build and engine one database, kept across rounds,
# so the hot sensor's history grows from round to round. Each round, per build:
#
#   hot     durable POST /v1/calibrations, the paper's Table 1, every one to
#           sensor HOT (a new performed_at each time, growing with the
#           order of the requests, as a station's do);
#   fleet   the same spread over 1 000 sensors (FLEET-0 … FLEET-999);
#   coefficients, history, compensate   reads of HOT (its history as the
#           round left it);
#   2x-hot, 2x-fleet   (PostgreSQL) two replicas of the build on the one
#           database, CONNS/2 connections each, at once: their sum (p99:
#           the worse of the two).
#
# On PostgreSQL, pg_stat_activity is sampled every 50 ms during the write
# legs: the share of the database's busy backends in each wait event (what
# writers wait for). The machine's CPU busy over each write leg (/proc/stat)
# says whether the cores or something else was the limit. Prints Markdown for BENCHMARKS.md; every answer must be
# a 2xx (wrk's non-2xx count is checked). Measures, never judges.
# Usage: benches/writes.sh NAME=BIN NAME=BIN ...
#        (e.g. a5689ea=/tmp/a5689ea head=target/release/accelcal)
# A NAME ending in +sse runs its build with two clients of GET /v1/events
# open on each server (benches/sse.py: one reading, one that never reads);
# one ending in +stall with only the one that never reads. One ending in
# +hook has a webhook endpoint registered for every event, at a receiver on
# loopback that answers 204 (benches/sse.py receive); one ending in +dead
# at one that takes connections and never answers (benches/sse.py
# blackhole: every attempt waits for --webhook-timeout).
# PG_URL: a PostgreSQL server with trust auth (postgres://postgres@127.0.0.1:5432).
set -euo pipefail
cd "$(dirname "$0")/.."
CONNS=${CONNS:-64}
LEG=${LEG:-10}
ROUNDS=${ROUNDS:-3}
ENGINES=${ENGINES:-sqlite postgres}
PG=${PG_URL:-postgres://postgres@127.0.0.1:5432}
WORK=$(mktemp -d)
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
  for db in $(psql "$PG/test" -Atc "SELECT datname FROM pg_database WHERE datname LIKE 'writes_bench_%'" 2>/dev/null); do
    psql "$PG/test" -qc "DROP DATABASE $db WITH (FORCE)" >/dev/null 2>&1 || true
  done
  rm -rf "$WORK"
}
trap cleanup EXIT
export ACCELCAL_ADMIN_TOKEN="$(head -c 32 /dev/urandom | base64)"
export ACCELCAL_WEBHOOK_ALLOW_PRIVATE=true # the +hook and +dead receivers, on loopback
command -v wrk >/dev/null || { echo "wrk is not installed (apt-get install wrk)" >&2; exit 1; }

NAMES=(); declare -A BIN
for arg in "$@"; do
  name=${arg%%=*}; NAMES+=("$name"); BIN[$name]=$(realpath "${arg#*=}")
done
[ ${#NAMES[@]} -ge 1 ] || { sed -n 2,31p "$0" >&2; exit 2; }

port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
# serve NAME DATABASE → prints the port; the pid lands in PIDS.
serve() {
  local p; p=$(port)
  "${BIN[$1]}" serve --listen 127.0.0.1:$p --database "$2" >>"$WORK/$1.log" 2>&1 &
  PIDS+=($!); echo "$! $p"
}
ready() { for _ in $(seq 200); do curl -sf "localhost:$1/readyz" >/dev/null && return; sleep 0.1; done; cat "$WORK"/*.log >&2; exit 1; }

# The Lua of a submission leg: SENSORS sensors named PREFIX…, performed_at
# unique across threads and legs (OFFSET).
python3 - "$WORK/template.json" <<'PY'
import json, sys
b = json.load(open("examples/paper-table1.json"))
b["sensor_id"] = "@SENSOR@"; b["performed_at"] = "@AT@"
open(sys.argv[1], "w").write(json.dumps(b))
PY
cat >"$WORK/submit.lua" <<'LUA'
local template, sensors, prefix, offset, stride, slot
local threads = {}
local counter = 0
function setup(thread)
  thread:set("tid", #threads)
  table.insert(threads, thread)
end
function init(args)
  local f = io.open(os.getenv("TEMPLATE")); template = f:read("*a"); f:close()
  sensors = tonumber(os.getenv("SENSORS")); prefix = os.getenv("PREFIX")
  -- performed_at grows with the order of the requests across wrk's
  -- threads (and both replicas' clients: STRIDE threads in all, this
  -- client's first FIRST), as a station's tests follow each other.
  offset = tonumber(os.getenv("OFFSET")); stride = tonumber(os.getenv("STRIDE"))
  slot = tonumber(os.getenv("FIRST")) + tid
  wrk.method = "POST"
  wrk.headers["Content-Type"] = "application/json"
  wrk.headers["Authorization"] = "Bearer " .. os.getenv("ACCELCAL_ADMIN_TOKEN")
end
function request()
  counter = counter + 1
  local n = offset + counter * stride + slot
  local sensor = prefix
  if sensors > 1 then sensor = prefix .. (n % sensors) end
  local at = os.date("!%Y-%m-%dT%H:%M:%SZ", 946684800 + n)
  local body = template:gsub("@SENSOR@", sensor):gsub("@AT@", at)
  return wrk.format(nil, "/v1/calibrations", nil, body)
end
LUA
cat >"$WORK/read.lua" <<'LUA'
function init(args)
  wrk.headers["Authorization"] = "Bearer " .. os.getenv("ACCELCAL_ADMIN_TOKEN")
  if os.getenv("BODY") ~= "" then
    wrk.method = "POST"; wrk.body = os.getenv("BODY")
    wrk.headers["Content-Type"] = "application/json"
  end
end
LUA
COMPENSATE=$(python3 -c 'import json; print(json.dumps({"outputs": [-1.216 + 0.024 * k for k in range(100)]}))')

# wrk_leg PORT CONNS SCRIPT PATH → "req/s p99ms" (aborts on a non-2xx).
wrk_leg() {
  local out threads=$(( $2 < 2 ? 1 : 2 ))
  out=$(STRIDE=${STRIDE:-$threads} FIRST=${FIRST:-0} wrk -t$threads -c$2 -d${LEG}s --latency -s "$3" "http://127.0.0.1:$1$4")
  if grep -q "Non-2xx\|Socket errors" <<<"$out"; then echo "$out" >&2; exit 1; fi
  local rps p99
  rps=$(awk '/^Requests\/sec/ {print $2}' <<<"$out")
  p99=$(awk '$1 == "99%" { v = $2; if (v ~ /us$/) { sub(/us/, "", v); v /= 1000 } else if (v ~ /ms$/) { sub(/ms/, "", v) } else if (v ~ /s$/) { sub(/s/, "", v); v *= 1000 } print v }' <<<"$out")
  echo "$rps $p99"
}

# Samples the wait events of database $1's busy backends into $2 until killed.
sample_waits() {
  while true; do
    psql "$PG/test" -Atc "SELECT coalesce(wait_event_type || ':' || wait_event, 'CPU') FROM pg_stat_activity \
      WHERE datname = '$1' AND state = 'active' AND pid <> pg_backend_pid()" >>"$2" 2>/dev/null || true
    sleep 0.05
  done
}
# The machine's CPU counters (/proc/stat: all jiffies, idle + iowait).
cpu_mark() { awk '/^cpu / { t = 0; for (i = 2; i <= NF; i++) t += $i; print t, $5 + $6 }' /proc/stat; }
# busy_since MARK → the share of the machine's CPU time busy since MARK, %.
busy_since() {
  local t0 i0 t1 i1; read -r t0 i0 <<<"$1"; read -r t1 i1 < <(cpu_mark)
  awk -v t="$((t1 - t0))" -v i="$((i1 - i0))" 'BEGIN { printf "%.0f", 100 * (t - i) / t }'
}
waits_summary() {
  sort "$1" | uniq -c | sort -rn | awk -v total="$(wc -l <"$1")" 'NR <= 4 { printf "%s%s %.0f%%", (NR > 1 ? ", " : ""), $2, 100 * $1 / total }'
}

declare -A RES
OFFSET=0
for engine in $ENGINES; do
  for name in "${NAMES[@]}"; do
    if [ "$engine" = postgres ]; then
      db=writes_bench_${name//[^a-z0-9]/_}
      psql "$PG/test" -qc "DROP DATABASE IF EXISTS $db WITH (FORCE)" -c "CREATE DATABASE $db"
    fi
  done
  for round in $(seq "$ROUNDS"); do
    # The builds' order rotates from round to round: the last of a round
    # runs after the others' write legs, which a run on two shared cores
    # feels.
    shift_by=$(( (round - 1) % ${#NAMES[@]} ))
    for name in "${NAMES[@]:shift_by}" "${NAMES[@]:0:shift_by}"; do
      if [ "$engine" = postgres ]; then database="$PG/writes_bench_${name//[^a-z0-9]/_}"; else database="$WORK/$name.db"; fi
      read -r pid p < <(serve "$name" "$database"); ready "$p"
      clients=()
      if [[ $name == *+sse ]]; then
        python3 benches/sse.py read "http://127.0.0.1:$p" "$ACCELCAL_ADMIN_TOKEN" & clients+=($!)
      fi
      if [[ $name == *+sse || $name == *+stall ]]; then
        python3 benches/sse.py stall "http://127.0.0.1:$p" "$ACCELCAL_ADMIN_TOKEN" & clients+=($!)
        PIDS+=("${clients[@]}")
      fi
      if [[ $name == *+hook || $name == *+dead ]]; then
        hp=$(port)
        if [[ $name == *+hook ]]; then python3 benches/sse.py receive "$hp" & else python3 benches/sse.py blackhole "$hp" & fi
        clients+=($!); PIDS+=($!)
        sleep 0.3
        curl -sf -o /dev/null -X PUT "localhost:$p/v1/webhooks/bench" -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" \
          -H 'Content-Type: application/json' -d "{\"url\": \"http://127.0.0.1:$hp/hook\"}"
      fi
      for leg in hot fleet; do
        [ $leg = hot ] && { sensors=1; prefix=HOT; } || { sensors=1000; prefix=FLEET-; }
        OFFSET=$((OFFSET + 1000000))
        : >"$WORK/waits"
        if [ "$engine" = postgres ]; then sample_waits "${database##*/}" "$WORK/waits" & SAMPLER=$!; fi
        mark=$(cpu_mark)
        r=$(TEMPLATE="$WORK/template.json" SENSORS=$sensors PREFIX=$prefix OFFSET=$OFFSET wrk_leg "$p" "$CONNS" "$WORK/submit.lua" /)
        RES[$engine,$name,$leg,busy,$round]=$(busy_since "$mark")
        if [ "$engine" = postgres ]; then kill $SAMPLER; wait $SAMPLER 2>/dev/null || true; RES[$engine,$name,$leg,waits,$round]=$(waits_summary "$WORK/waits"); fi
        RES[$engine,$name,$leg,$round]=$r
      done
      RES[$engine,$name,history_size,$round]=$(curl -s "localhost:$p/v1/sensors/HOT" -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" | python3 -c 'import json,sys; print(json.load(sys.stdin).get("calibration_count", "?"))')
      RES[$engine,$name,coefficients,$round]=$(BODY= wrk_leg "$p" "$CONNS" "$WORK/read.lua" /v1/sensors/HOT/coefficients)
      RES[$engine,$name,history,$round]=$(BODY= wrk_leg "$p" "$CONNS" "$WORK/read.lua" "/v1/sensors/HOT/calibrations?limit=20")
      RES[$engine,$name,compensate,$round]=$(BODY=$COMPENSATE wrk_leg "$p" "$CONNS" "$WORK/read.lua" /v1/sensors/HOT/compensate)
      if [ "$engine" = postgres ]; then
        read -r pid2 p2 < <(serve "$name" "$database"); ready "$p2"
        for leg in hot fleet; do
          [ $leg = hot ] && { sensors=1; prefix=HOT; } || { sensors=1000; prefix=FLEET-; }
          OFFSET=$((OFFSET + 1000000))
          : >"$WORK/waits"; sample_waits "${database##*/}" "$WORK/waits" & SAMPLER=$!
          mark=$(cpu_mark)
          (STRIDE=4 FIRST=0 TEMPLATE="$WORK/template.json" SENSORS=$sensors PREFIX=$prefix OFFSET=$OFFSET wrk_leg "$p" $((CONNS / 2)) "$WORK/submit.lua" / >"$WORK/r1") &
          w1=$!
          STRIDE=4 FIRST=2 TEMPLATE="$WORK/template.json" SENSORS=$sensors PREFIX=$prefix OFFSET=$OFFSET wrk_leg "$p2" $((CONNS / 2)) "$WORK/submit.lua" / >"$WORK/r2"
          wait $w1
          RES[$engine,$name,2x-$leg,busy,$round]=$(busy_since "$mark")
          kill $SAMPLER; wait $SAMPLER 2>/dev/null || true
          RES[$engine,$name,2x-$leg,waits,$round]=$(waits_summary "$WORK/waits")
          RES[$engine,$name,2x-$leg,$round]=$(awk '{ s += $1; if ($2 > m) m = $2 } END { printf "%.2f %s", s, m }' "$WORK/r1" "$WORK/r2")
        done
        kill "$pid2"; wait "$pid2" 2>/dev/null || true
      fi
      kill "$pid"; wait "$pid" 2>/dev/null || true
      for c in "${clients[@]}"; do kill "$c" 2>/dev/null || true; wait "$c" 2>/dev/null || true; done
    done
  done
done

fmt() { awk '{ printf "%\047d (%s)", $1, $2 }' <<<"$1"; }
echo "wrk, $CONNS connections, ${LEG} s legs, $ROUNDS rounds alternating ${NAMES[*]}; $(nproc) cores"
echo
first=${NAMES[0]}
header="| engine | leg |"; rule="|---|---|"
for name in "${NAMES[@]}"; do header+=" $name req/s (p99 ms), rounds 1…$ROUNDS |"; rule+="---|"; done
for name in "${NAMES[@]:1}"; do header+=" $name / $first |"; rule+="---|"; done
echo "$header"; echo "$rule"
for engine in $ENGINES; do
  legs="hot fleet coefficients history compensate"; [ "$engine" = postgres ] && legs="hot 2x-hot fleet 2x-fleet coefficients history compensate"
  for leg in $legs; do
    line="| $engine | $leg |"
    declare -A MEAN=()
    for name in "${NAMES[@]}"; do
      cells=(); sum=0
      for round in $(seq "$ROUNDS"); do
        v=${RES[$engine,$name,$leg,$round]}; cells+=("$(fmt "$v")"); sum=$(awk -v s="$sum" -v a="${v%% *}" 'BEGIN { print s + a }')
      done
      MEAN[$name]=$(awk -v s="$sum" -v n="$ROUNDS" 'BEGIN { print s / n }')
      line+=" $(IFS=/; echo "${cells[*]}" | sed 's|/| / |g') |"
    done
    for name in "${NAMES[@]:1}"; do line+=" $(awk -v a="${MEAN[$name]}" -v b="${MEAN[$first]}" 'BEGIN { printf "%.2f", a / b }') |"; done
    echo "$line"
  done
done
echo
echo "HOT's calibrations after each round:"
for engine in $ENGINES; do for name in "${NAMES[@]}"; do
  echo -n "- $engine $name:"; for round in $(seq "$ROUNDS"); do echo -n " ${RES[$engine,$name,history_size,$round]}"; done; echo
done; done
echo
echo "The machine's CPU busy during the write legs (/proc/stat, every process: servers, database, wrk), %, rounds 1…$ROUNDS:"
for engine in $ENGINES; do
  legs="hot fleet"; [ "$engine" = postgres ] && legs="hot 2x-hot fleet 2x-fleet"
  for name in "${NAMES[@]}"; do for leg in $legs; do
    echo -n "- $engine $name $leg:"; for round in $(seq "$ROUNDS"); do echo -n " ${RES[$engine,$name,$leg,busy,$round]}"; done; echo
  done; done
done
if [[ " $ENGINES " == *" postgres "* ]]; then
  echo
  echo "PostgreSQL's busy backends by wait event during the write legs (last round; CPU = not waiting):"
  for name in "${NAMES[@]}"; do for leg in hot 2x-hot fleet 2x-fleet; do
    echo "- $name $leg: ${RES[postgres,$name,$leg,waits,$ROUNDS]}"
  done; done
fi
