#!/usr/bin/env bash
# The OpenAPI contract checked against the running server by schemathesis:
# every operation, positive and negative data, all phases (examples,
# coverage, fuzzing, stateful), all checks (see schemathesis.toml).
# Usage: tests/contract/run.sh [path/to/accelcal] [max-examples]
# The seed is fixed for reproducible CI (SCHEMATHESIS_SEED=… to explore);
# one worker, because CPython 3.11's ast module is not thread-safe and
# hypothesis uses it while generating (a tool crash, not a finding).
# GET /v1/events is left out: its answer is a stream that does not end,
# which schemathesis would wait for; tests/api/events.rs reads it with a
# real client against the running server and checks each event against
# the contract's LiveEvent.
set -euo pipefail
BIN=$(realpath "${1:-$(dirname "$0")/../../target/debug/accelcal}")
cd "$(dirname "$0")/../.."
EXAMPLES=${2:-100}
ST=${SCHEMATHESIS:-schemathesis}
WORK=$(mktemp -d)
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
export ACCELCAL_TOKEN="$(head -c 32 /dev/urandom | base64)"
# Schemathesis sends hundreds of invalid credentials from one address on
# purpose (its authentication checks); the per-address throttle, which would
# answer them 429 after 20, is set out of its way (tests/api cover it).
ACCELCAL_ADMIN_TOKEN=$ACCELCAL_TOKEN "$BIN" serve --listen 127.0.0.1:$PORT \
  --database "$WORK/accelcal.db" --log-format json --auth-failure-burst 100000 >/dev/null 2>"$WORK/server.log" &
PID=$!
trap 'kill $PID 2>/dev/null || :; wait $PID 2>/dev/null || :; rm -rf "$WORK"' EXIT
for _ in $(seq 50); do curl -sf http://127.0.0.1:$PORT/healthz >/dev/null && break; sleep 0.1; done

"$ST" --config-file tests/contract/schemathesis.toml run openapi.yaml \
  --url http://127.0.0.1:$PORT --mode all --phases examples,coverage,fuzzing,stateful \
  --max-examples "$EXAMPLES" --no-color --workers 1 --seed "${SCHEMATHESIS_SEED:-20261122}" \
  --exclude-operation-id streamEvents

# Each kind's stored result document against getCalibration's schema.
"$(dirname "$(command -v "$ST")")/python3" tests/contract/documents.py "http://127.0.0.1:$PORT" "$ACCELCAL_TOKEN"

# Whatever schemathesis thought, the server itself must never have answered 5xx.
if grep -q '"status":5[0-9][0-9]' "$WORK/server.log"; then
  echo "contract: the server logged 5xx answers:" >&2
  grep '"status":5[0-9][0-9]' "$WORK/server.log" | head -20 >&2
  exit 1
fi
kill -TERM $PID && wait $PID
trap 'rm -rf "$WORK"' EXIT
echo "contract: ok"
