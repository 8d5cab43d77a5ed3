# Sourced by the shell tests that talk to one tesserad (cli_test.sh, readme_test.sh): a scratch
# directory $work removed at exit, fail(), and start_tesserad TESSERAD, which starts the daemon
# on a free loopback port, waits for it (60 s at most) and exports TESSERA_SERVER. The daemon is
# stopped (SIGTERM) at exit.
work=$(mktemp -d)
pid=""
cleanup() {
  if [[ -n $pid ]]; then kill -TERM "$pid" 2>/dev/null || true; wait "$pid" 2>/dev/null || true; fi
  rm -rf "$work"
}
trap cleanup EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

start_tesserad() {
  "$1" --listen=127.0.0.1:0 --port_file="$work/port" --log_level=warn &
  pid=$!
  for _ in $(seq 600); do [[ -s $work/port ]] && break; sleep 0.1; done
  [[ -s $work/port ]] || fail "tesserad did not start"
  export TESSERA_SERVER="127.0.0.1:$(cat "$work/port")"
}
