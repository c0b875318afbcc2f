#!/usr/bin/env bash
# accelcal's Digital Calibration Certificates read by PTB's own libraries:
# starts accelcal (laboratory configured) on a fresh SQLite database, and
# tests/dcc/read.py approves a single-axis calibration, a triad and the
# temperature models of both whose free text is hostile (markup, `]]>`,
# quotes, astral and combining characters), then reads their DCCs with
# dcc-json-toolkit's content validation and every si:unit with dsiUnits.
# Needs the packages in tests/dcc/requirements.txt (.ci/run installs them
# in its venv).
# Usage: tests/dcc/run.sh [path/to/accelcal]
set -euo pipefail
BIN=$(realpath "${1:-$(dirname "$0")/../../target/debug/accelcal}")
cd "$(dirname "$0")/../.."
WORK=$(mktemp -d)
. tests/server.sh
export ACCELCAL_LAB_NAME="Inertial <Test> & \"Lab\"" ACCELCAL_LAB_ADDRESS="Bahnhofstrasse 1, 8001 Zürich" \
  ACCELCAL_LAB_COUNTRY=CH ACCELCAL_LAB_ACCREDITATION="SAS SCS 0999"
start_server sqlite dcc "$WORK/server.log" "$WORK/server.log"
python3 tests/dcc/read.py "$BASE" "$WORK" || { tail -n 20 "$WORK/server.log" >&2; exit 1; }
