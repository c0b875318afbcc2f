#!/usr/bin/env bash
# accelcal's pages in a real browser, and its metrics through promtool.
# Starts accelcal (and a second process on a database of its own, one-second
# sessions, for the expiry check) with metrics on, both looking at a page
# stream's session every second (`--events-heartbeat 1`, so that the pages'
# script is seen to stop once its session ends), the first without the
# clock's status scan during the run (`--status-scan 3600`: the live check
# counts a sensor page's events, and a scan that found the sensor overdue
# would add one), runs tests/ui/browser.mjs
# in Debian's chromium, then checks the scraped metrics with
# `promtool check metrics`. Needs chromium, node/npm, promtool and pdftotext (.ci/run
# installs them); screenshots land in target/ui-screenshots/.
# Usage: tests/ui/run.sh [path/to/accelcal]
set -euo pipefail
BIN=$(realpath "${1:-$(dirname "$0")/../../target/debug/accelcal}")
cd "$(dirname "$0")/../.."
[ -d tests/ui/node_modules/playwright-core ] || npm ci --prefix tests/ui --no-audit --no-fund --silent
WORK=$(mktemp -d)
free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
PORT=$(free_port); SHORT_PORT=$(free_port); METRICS_PORT=$(free_port)
export ACCELCAL_ADMIN_TOKEN="$(head -c 32 /dev/urandom | base64)"
"$BIN" serve --listen 127.0.0.1:$PORT --database "$WORK/accelcal.db" \
  --metrics-listen 127.0.0.1:$METRICS_PORT --events-heartbeat 1 --status-scan 3600 \
  --log-format json >"$WORK/server.log" 2>&1 &
PID=$!
trap 'kill $PID ${SHORT_PID:-} 2>/dev/null; wait 2>/dev/null; rm -rf "$WORK"' EXIT
for _ in $(seq 100); do curl -sf http://127.0.0.1:$PORT/healthz >/dev/null && break; sleep 0.1; done
"$BIN" serve --listen 127.0.0.1:$SHORT_PORT --database "$WORK/short.db" --session-ttl 1 \
  --events-heartbeat 1 --log-format json >"$WORK/short.log" 2>&1 &
SHORT_PID=$!
for _ in $(seq 100); do curl -sf http://127.0.0.1:$SHORT_PORT/healthz >/dev/null && break; sleep 0.1; done

ACCELCAL_URL=http://127.0.0.1:$PORT ACCELCAL_SHORT_SESSION_URL=http://127.0.0.1:$SHORT_PORT \
  SCREENSHOTS=target/ui-screenshots node tests/ui/browser.mjs

curl -sf http://127.0.0.1:$METRICS_PORT/metrics >"$WORK/metrics.txt"
promtool check metrics <"$WORK/metrics.txt"
for metric in accelcal_http_requests_total accelcal_http_request_duration_seconds_bucket \
  accelcal_http_requests_in_flight accelcal_submissions_total accelcal_verdicts_total \
  accelcal_storage_operation_duration_seconds_bucket accelcal_build_info \
  accelcal_storage_write_batch_size_bucket accelcal_sensor_cache_total \
  accelcal_sensor_cache_writes_total accelcal_reviews_total \
  accelcal_log_lines_dropped_total accelcal_events_clients_ended_total; do
  grep -q "^$metric" "$WORK/metrics.txt" || { echo "metrics: $metric missing" >&2; exit 1; }
done
echo "metrics: promtool check passed"
if grep -q '"status":5[0-9][0-9]' "$WORK/server.log" "$WORK/short.log"; then
  echo "ui: the server logged 5xx answers" >&2; exit 1
fi
echo "ui: ok"
