#!/usr/bin/env bash
# A sensor's history: what its reads cost as its calibrations grow (issue 48
# item 3). Stores the paper's Table 1 once through BIN on a fresh SQLite
# file, copies that calibration N times for sensor HOT with sqlite3 (one
# hour apart, rows as the service stored the first), and times the sensor,
# its coefficients, a history page and its stability — the median of 15
# requests after 3 — then a durable submission to that sensor and a
# reviewer's approval of one of its calibrations (the median of 15 each,
# every one a new act), per N. Measures, never judges (BENCHMARKS.md "A
# sensor's history").
# Usage: benches/history.sh BIN [N ...]     (N: 40 2000 20000 100000)
# KEEP_DB=path keeps the last database there (to profile an act on it).
set -euo pipefail
BIN=$(realpath "$1"); shift
SIZES=${*:-40 2000 20000 100000}
KEEP=${KEEP_DB:-}
cd "$(dirname "$0")/.."
WORK=$(mktemp -d)
trap 'kill ${PID:-} 2>/dev/null || true; rm -rf "$WORK"' EXIT
export ACCELCAL_ADMIN_TOKEN="$(head -c 32 /dev/urandom | base64)"
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
serve() {
  "$BIN" serve --listen 127.0.0.1:$PORT --database "$1" >"$WORK/serve.log" 2>&1 &
  PID=$!
  for _ in $(seq 100); do curl -sf localhost:$PORT/readyz >/dev/null && return; sleep 0.1; done
  cat "$WORK/serve.log" >&2; exit 1
}
stop() { kill $PID; wait $PID 2>/dev/null || true; PID=; }
get() { curl -s -o /dev/null -w '%{http_code} %{time_total}\n' "localhost:$PORT$1" -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN"; }
median() {
  for _ in 1 2 3; do get "$1" >/dev/null; done
  for _ in $(seq 15); do get "$1"; done | awk '$1 != 200 { print "status " $1 > "/dev/stderr"; exit 1 } { print $2 }' \
    | sort -n | sed -n 8p | awk '{ printf "%.1f", $1 * 1000 }'
}

# Times 15 acts: `act I` prints `code seconds` for act I (1..15).
median_act() {
  for i in $(seq 15); do "$1" "$i"; done | awk '$1 !~ /^2/ { print "status " $1 > "/dev/stderr"; exit 1 } { print $2 }' \
    | sort -n | sed -n 8p | awk '{ printf "%.1f", $1 * 1000 }'
}
submit() {
  curl -s -o /dev/null -w '%{http_code} %{time_total}\n' -X POST localhost:$PORT/v1/calibrations \
    -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" -H 'Content-Type: application/json' \
    -H "Idempotency-Key: history-$1" --data-binary @"$WORK/hot.json"
}
approve() {
  curl -s -o /dev/null -w '%{http_code} %{time_total}\n' -X POST \
    "localhost:$PORT/v1/calibrations/$(printf '00000000-0000-7000-8000-%012x' "$1")/review" \
    -H "Authorization: Bearer $REVIEWER" -H 'Content-Type: application/json' \
    -d '{"decision": "approve", "comment": "history benchmark"}'
}

python3 -c 'import json,sys; b=json.load(open("examples/paper-table1.json")); b["sensor_id"]="HOT"; json.dump(b, sys.stdout)' >"$WORK/hot.json"
serve "$WORK/seed.db"
curl -sf -o /dev/null -X POST localhost:$PORT/v1/calibrations -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" \
  -H 'Content-Type: application/json' --data-binary @examples/paper-table1.json
REVIEWER=$(curl -sf -X POST localhost:$PORT/v1/tokens -H "Authorization: Bearer $ACCELCAL_ADMIN_TOKEN" \
  -H 'Content-Type: application/json' -d '{"role": "reviewer", "holder": "Bench Reviewer"}' \
  | python3 -c 'import json,sys; print(json.load(sys.stdin)["token"])')
stop
echo "| calibrations of the sensor | sensor | coefficients | history page (50) | stability | submit | approve |"
echo "|---|---|---|---|---|---|---|"
for n in $SIZES; do
  cp "$WORK/seed.db" "$WORK/h.db"
  sqlite3 "$WORK/h.db" <<SQL
WITH RECURSIVE k(i) AS (SELECT 1 UNION ALL SELECT i + 1 FROM k WHERE i < $n)
INSERT INTO calibrations (id, sensor_id, station_id, performed_at, received_at, unit, model, runs,
  coefficients, std_errors, expanded, content_type, submitted_by, sensor_type, verdict, due_at, triad,
  result, submission)
SELECT printf('00000000-0000-7000-8000-%012x', i), 'HOT', station_id,
  strftime('%Y-%m-%dT%H:%M:%S.000000Z', '2000-01-01', printf('+%d hours', i)), received_at, unit,
  model, runs, coefficients, std_errors, expanded, content_type, submitted_by, sensor_type, verdict,
  due_at, triad, result, submission
FROM calibrations, k WHERE sensor_id = 'PAPER-2005';
CREATE TEMP TABLE hot AS SELECT * FROM sensors WHERE sensor_id = 'PAPER-2005';
UPDATE hot SET sensor_id = 'HOT', calibration_count = $n,
  latest_calibration_id = printf('00000000-0000-7000-8000-%012x', $n),
  latest_performed_at = (SELECT max(performed_at) FROM calibrations WHERE sensor_id = 'HOT');
INSERT INTO sensors SELECT * FROM hot;
SQL
  serve "$WORK/h.db"
  echo "| $n | $(median /v1/sensors/HOT) ms | $(median /v1/sensors/HOT/coefficients) ms | $(median '/v1/sensors/HOT/calibrations?limit=50') ms | $(median /v1/sensors/HOT/stability) ms | $(median_act submit) ms | $(median_act approve) ms |"
  stop
  if [ -n "$KEEP" ]; then cp "$WORK/h.db" "$KEEP"; fi
done
