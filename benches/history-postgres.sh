#!/usr/bin/env bash
# A sensor's history on PostgreSQL (issue 48 item 3): benches/history.sh's
# measure on a fresh database of the server ACCELCAL_TEST_POSTGRES_URL names
# (default postgres://postgres@127.0.0.1:5432/test), the rows copied with
# psql (jsonb_populate_record), then ANALYZE; dropped after each N. Prints
# milliseconds: sensor, coefficients, history page, stability, submit, approve.
# PLANS=FILE: also write to FILE the plan, with actual times (auto_explain,
# EXPLAIN ANALYZE), of every statement the service runs for the timed acts
# (needs read access to PostgreSQL's log, PG_LOG, default Debian's).
# Usage: benches/history-postgres.sh BIN N...
set -euo pipefail
BIN=$(realpath "$1"); shift
cd "$(dirname "$0")/.."
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
export ACCELCAL_ADMIN_TOKEN="$(head -c 32 /dev/urandom | base64)"
ADMIN_URL=${ACCELCAL_TEST_POSTGRES_URL:-postgres://postgres@127.0.0.1:5432/test}
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
get() { curl -s -o /dev/null -w '%{http_code} %{time_total}\n' "localhost:$PORT$1" -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN"; }
median() { for _ in 1 2 3; do get "$1" >/dev/null; done; for _ in $(seq 15); do get "$1"; done | awk '{print $2}' | sort -n | sed -n 8p | awk '{ printf "%.1f", $1 * 1000 }'; }
python3 -c 'import json,sys; b=json.load(open("examples/paper-table1.json")); b["sensor_id"]="HOT"; json.dump(b, sys.stdout)' >"$WORK/hot.json"
for n in "$@"; do
  DB=accelcal_pghist_$$_$n
  psql -q $ADMIN_URL -c "CREATE DATABASE $DB" >/dev/null
  URL=${ADMIN_URL%/*}/$DB
  "$BIN" serve --listen 127.0.0.1:$PORT --database "$URL" >"$WORK/serve.log" 2>&1 & PID=$!
  for _ in $(seq 100); do curl -sf localhost:$PORT/readyz >/dev/null && break; sleep 0.1; done
  curl -sf -o /dev/null -X POST localhost:$PORT/v1/calibrations -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" -H 'Content-Type: application/json' --data-binary @examples/paper-table1.json
  R=$(curl -sf -X POST localhost:$PORT/v1/tokens -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" -H 'Content-Type: application/json' -d '{"role": "reviewer", "holder": "Bench"}' | python3 -c 'import json,sys; print(json.load(sys.stdin)["token"])')
  psql -q "$URL" >/dev/null <<SQL
INSERT INTO calibrations SELECT (jsonb_populate_record(NULL::calibrations, to_jsonb(c) || jsonb_build_object(
  'id', ('00000000-0000-7000-8000-' || lpad(to_hex(i), 12, '0'))::uuid, 'sensor_id', 'HOT',
  'performed_at', timestamptz '2000-01-01 00:00:00+00' + make_interval(hours => i)))).*
FROM calibrations c, generate_series(1, $n) i WHERE c.sensor_id = 'PAPER-2005';
INSERT INTO sensors SELECT (jsonb_populate_record(NULL::sensors, to_jsonb(s) || jsonb_build_object(
  'sensor_id', 'HOT', 'calibration_count', $n,
  'latest_calibration_id', ('00000000-0000-7000-8000-' || lpad(to_hex($n), 12, '0'))::uuid,
  'latest_performed_at', timestamptz '2000-01-01 00:00:00+00' + make_interval(hours => $n)))).*
FROM sensors s WHERE s.sensor_id = 'PAPER-2005';
ANALYZE;
SQL
  if [ -n "${PLANS:-}" ]; then
    # New sessions of this database log each statement's plan as run.
    psql -q "$URL" -c "ALTER DATABASE $DB SET session_preload_libraries = 'auto_explain'" \
      -c "ALTER DATABASE $DB SET auto_explain.log_min_duration = 0" \
      -c "ALTER DATABASE $DB SET auto_explain.log_analyze = on" >/dev/null
    kill $PID; wait $PID 2>/dev/null || true
    "$BIN" serve --listen 127.0.0.1:$PORT --database "$URL" >"$WORK/serve.log" 2>&1 & PID=$!
    for _ in $(seq 100); do curl -sf localhost:$PORT/readyz >/dev/null && break; sleep 0.1; done
    LOG=${PG_LOG:-/var/log/postgresql/postgresql-15-main.log}; FROM=$(wc -c <"$LOG")
  fi
  sub=$(for i in $(seq 15); do curl -s -o /dev/null -w '%{time_total}\n' -X POST localhost:$PORT/v1/calibrations -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" -H 'Content-Type: application/json' -H "Idempotency-Key: h-$i" --data-binary @"$WORK/hot.json"; done | sort -n | sed -n 8p | awk '{ printf "%.1f", $1 * 1000 }')
  app=$(for i in $(seq 15); do curl -s -o /dev/null -w '%{time_total}\n' -X POST "localhost:$PORT/v1/calibrations/$(printf '00000000-0000-7000-8000-%012x' $i)/review" -H "Authorization: Bearer $R" -H 'Content-Type: application/json' -d '{"decision":"approve","comment":"b"}'; done | sort -n | sed -n 8p | awk '{ printf "%.1f", $1 * 1000 }')
  if [ -n "${PLANS:-}" ]; then
    { echo "## N = $n"; tail -c +$((FROM + 1)) "$LOG"; } >>"$PLANS"
  fi
  echo "| $n | $(median /v1/sensors/HOT) | $(median /v1/sensors/HOT/coefficients) | $(median '/v1/sensors/HOT/calibrations?limit=50') | $(median /v1/sensors/HOT/stability) | $sub | $app |"
  kill $PID; wait $PID 2>/dev/null || true
  psql -q $ADMIN_URL -c "DROP DATABASE $DB WITH (FORCE)" >/dev/null
done
