# Sourced by the shell tests (walkthrough, generated clients): a free port,
# and the service started on it with a fresh database — a SQLite file, or a
# PostgreSQL database on the server ACCELCAL_TEST_POSTGRES_URL names
# (default postgres://postgres@127.0.0.1:5432/test) — stopped, and the
# database dropped, when the script exits.

free_port() {
  python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'
}

# start_server ENGINE NAME OUT ERR — "$BIN" serve on a free port with a
# random admin token (exported as ACCELCAL_ADMIN_TOKEN), on a fresh database
# called NAME in "$WORK", its stdout to OUT and stderr to ERR (the same
# file for both: one log); returns once
# /readyz answers. Sets PORT, BASE, DATABASE, DROP (the command that drops
# the database) and PID; the EXIT trap stops it and removes "$WORK".
start_server() {
  local engine=$1 name=$2 out=$3 err=$4
  PORT=$(free_port)
  BASE=http://127.0.0.1:$PORT
  ACCELCAL_ADMIN_TOKEN="$(head -c 32 /dev/urandom | base64)"
  export ACCELCAL_ADMIN_TOKEN
  case $engine in
    sqlite) DATABASE=$WORK/$name.db; DROP=: ;;
    postgres)
      local admin_url=${ACCELCAL_TEST_POSTGRES_URL:-postgres://postgres@127.0.0.1:5432/test}
      local db=accelcal_${name}_$$
      psql -q "$admin_url" -c "CREATE DATABASE $db" >/dev/null
      DATABASE=${admin_url%/*}/$db
      DROP="psql -q $admin_url -c 'DROP DATABASE IF EXISTS $db WITH (FORCE)'" ;;
    *) echo "engine must be sqlite or postgres, not $engine" >&2; exit 2 ;;
  esac
  if [ "$out" = "$err" ]; then
    "$BIN" serve --listen 127.0.0.1:$PORT --database "$DATABASE" >"$out" 2>&1 &
  else
    "$BIN" serve --listen 127.0.0.1:$PORT --database "$DATABASE" >"$out" 2>"$err" &
  fi
  PID=$!
  # Every step may fail (a test that killed the server itself, a database
  # already gone) without changing the script's own exit status: under
  # `set -e` a failing command in the trap would end the script with 1.
  trap 'kill $PID 2>/dev/null || :; wait $PID 2>/dev/null || :; eval "$DROP" >/dev/null 2>&1 || :; rm -rf "$WORK"' EXIT
  for _ in $(seq 100); do curl -sf "$BASE/readyz" >/dev/null && return 0; sleep 0.1; done
  echo "the service did not become ready on $BASE" >&2
  cat "$err" >&2
  exit 1
}
