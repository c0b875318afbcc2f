#!/usr/bin/env bash
# Signed Digital Calibration Certificates checked by outside verifiers
# (issue 46): starts accelcal on ENGINE (sqlite or postgres) signing with the
# test key tests/data/signing/lab.key, and tests/dcc/signed.py approves a
# single-axis and a triad calibration and checks their DCCs with Debian's
# xmlsec1 and Python's signxml (and accelcal's own verifier), forged copies
# refused by all; then restarts it on the same database with a rotated key
# and checks that what was issued stays as issued and still verifies. Needs
# xmlsec1 and tests/dcc/requirements.txt (.ci/run installs both).
# Usage: tests/dcc/signed.sh [path/to/accelcal] [sqlite|postgres]
set -euo pipefail
BIN=$(realpath "${1:-$(dirname "$0")/../../target/debug/accelcal}")
ENGINE=${2:-sqlite}
cd "$(dirname "$0")/../.."
WORK=$(mktemp -d)
. tests/server.sh
cp tests/data/signing/{lab,rotated}.{key,pem} tests/data/signing/ca.pem "$WORK/"
chmod 600 "$WORK"/*.key
export ACCELCAL_LAB_NAME="Inertial Test Lab" ACCELCAL_LAB_ADDRESS="Bahnhofstrasse 1, 8001 Zürich" \
  ACCELCAL_LAB_COUNTRY=CH ACCELCAL_LAB_ACCREDITATION="SAS SCS 0999" \
  ACCELCAL_DCC_SIGNING_KEY=$WORK/lab.key ACCELCAL_DCC_SIGNING_CERT=$WORK/lab.pem
start_server "$ENGINE" signed "$WORK/server.log" "$WORK/server.log"
python3 tests/dcc/signed.py issue "$BASE" "$WORK" "$BIN" || { tail -n 20 "$WORK/server.log" >&2; exit 1; }

# The key rotated: the same database, the next certificate.
kill "$PID"; wait "$PID" 2>/dev/null || true
export ACCELCAL_DCC_SIGNING_KEY=$WORK/rotated.key ACCELCAL_DCC_SIGNING_CERT=$WORK/rotated.pem
PORT=$(free_port); BASE=http://127.0.0.1:$PORT
"$BIN" serve --listen "127.0.0.1:$PORT" --database "$DATABASE" >>"$WORK/server.log" 2>&1 &
PID=$!
for _ in $(seq 100); do curl -sf "$BASE/readyz" >/dev/null && break; sleep 0.1; done
python3 tests/dcc/signed.py rotated "$BASE" "$WORK" "$BIN" || { tail -n 20 "$WORK/server.log" >&2; exit 1; }
echo "signed DCCs ($ENGINE): verified by xmlsec1 and signxml, forgeries refused, rotation kept what was issued"
