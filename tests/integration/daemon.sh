# Sourced by the shell tests that start tesserad (cli_test.sh, readme_test.sh, farm_test.sh,
# stream_failover_test.sh): a scratch directory $work removed at exit, fail(), and
#   start_tesserad TESSERAD: one daemon on a free loopback port, waited for (60 s at most),
#     TESSERA_SERVER exported;
#   start_replicas N TESSERAD [FLAGS...]: N daemons, each with FLAGS and its log in $work/logI;
#     sets ports (HOST:PORT each), pids and servers (the comma list).
# Every daemon still running is stopped (SIGTERM) at exit.
work=$(mktemp -d)
pid=""
pids=()
cleanup() {
  for p in $pid "${pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  for p in $pid "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
  rm -rf "$work"
}
trap cleanup EXIT
fail() {
  echo "FAIL: $*" >&2
  tail -n 5 "$work"/log* >&2 2>/dev/null || true
  exit 1
}

start_replicas() {
  local n=$1 bin=$2 i
  shift 2
  ports=()
  for ((i = 0; i < n; i++)); do
    "$bin" --listen=127.0.0.1:0 --port_file="$work/port$i" --log_level=warn "$@" 2> "$work/log$i" &
    pids+=($!)
  done
  for ((i = 0; i < n; i++)); do
    for _ in $(seq 600); do [[ -s $work/port$i ]] && break; sleep 0.1; done
    [[ -s $work/port$i ]] || fail "tesserad $i did not start"
    ports+=("127.0.0.1:$(cat "$work/port$i")")
  done
  servers=$(IFS=,; echo "${ports[*]}")
}

start_tesserad() {
  "$1" --listen=127.0.0.1:0 --port_file="$work/port" --log_level=warn &
  pid=$!
  for _ in $(seq 600); do [[ -s $work/port ]] && break; sleep 0.1; done
  [[ -s $work/port ]] || fail "tesserad did not start"
  export TESSERA_SERVER="127.0.0.1:$(cat "$work/port")"
}
