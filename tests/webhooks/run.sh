#!/usr/bin/env bash
# Webhooks verified by the Standard Webhooks library, and nothing lost over
# kill -9 (issue 47 items 3 and 4): starts accelcal on ENGINE (sqlite or
# postgres) with loopback targets allowed and quick retries, and
# tests/webhooks/check.py registers an endpoint served by the example
# receiver (examples/webhooks/receiver.py, `standardwebhooks` from PyPI:
# tests/webhooks/requirements.txt, .ci/run installs it), then checks
# signatures, a receiver down and back up, rotation, and ROUNDS kill -9
# rounds under load.
# Usage: tests/webhooks/run.sh [path/to/accelcal] [sqlite|postgres] [ROUNDS]
set -euo pipefail
BIN=$(realpath "${1:-$(dirname "$0")/../../target/debug/accelcal}")
ENGINE=${2:-sqlite}
ROUNDS=${3:-5}
cd "$(dirname "$0")/../.."
WORK=$(mktemp -d)
. tests/server.sh
export ACCELCAL_WEBHOOK_ALLOW_PRIVATE=true ACCELCAL_WEBHOOK_RETRY_BASE=0.2 \
  ACCELCAL_WEBHOOK_RETRY_CAP=1 ACCELCAL_WEBHOOK_TIMEOUT=2 ACCELCAL_EVENTS_POLL_MS=50 \
  SERVER_LOG=$WORK/server.log
start_server "$ENGINE" webhooks "$WORK/server.log" "$WORK/server.log"
python3 tests/webhooks/check.py "$BIN" "$DATABASE" "$PORT" "$PID" "$ROUNDS" \
  || { tail -n 30 "$WORK/server.log" >&2; exit 1; }
echo "webhooks ($ENGINE): verified by standardwebhooks; nothing acknowledged lost over $ROUNDS kill -9 rounds"
