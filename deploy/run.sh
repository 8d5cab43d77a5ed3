#!/usr/bin/env bash
# Installs dependencies, builds tesserad and the tessera CLI, and starts tesserad with the
# built-in demo scene (scene id "demo") and the web viewer's gateway next to it; prints the
# viewer's URL. Ctrl-C (or SIGTERM) stops both cleanly.
#
# Extra arguments go to tesserad (e.g. ./deploy/run.sh --listen=0.0.0.0:50051 --max_scenes=8;
# see ./build/default/server/tesserad --help), except --web=HOST:PORT, where the viewer is
# served (default 127.0.0.1:8080), and --no-web. With tesserad's --token_file, give the gateway
# its token in $TESSERA_TOKEN (it inherits the environment).
set -euo pipefail
cd "$(dirname "$0")/.."

listen=127.0.0.1:50051
web=127.0.0.1:8080
args=()
while (($#)); do
  case "$1" in
    --web=*) web="${1#--web=}" ;;
    --web) web="${2:?--web needs HOST:PORT}"; shift ;;
    --no-web) web="" ;;
    --listen=*) listen="${1#--listen=}"; args+=("$1") ;;
    --listen) listen="${2:?--listen needs HOST:PORT}"; args+=("--listen=$2"); shift ;;
    *) args+=("$1") ;;
  esac
  shift
done

./deploy/install-deps.sh
cmake --preset default >/dev/null
cmake --build --preset default -j "$(nproc)" --target tesserad tessera tessera-render
if [[ -n $web ]]; then
  # Only when the lock file changed since the last install.
  if [[ ! -f clients/web/node_modules/.package-lock.json ||
        clients/web/package-lock.json -nt clients/web/node_modules/.package-lock.json ]]; then
    (cd clients/web && npm ci --omit=dev --no-audit --no-fund --loglevel=error)
  fi
fi

mkdir -p out
pids=()
stop() {
  trap - INT TERM EXIT
  for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
}
trap stop INT TERM EXIT

./build/default/server/tesserad --listen="${listen}" ${args[@]+"${args[@]}"} &
pids+=($!)
# tesserad's address as a client dials it (a wildcard listen address is dialled on loopback).
dial=${listen/0.0.0.0/127.0.0.1}
dial=${dial/\[::\]/127.0.0.1}

if [[ -n $web ]]; then
  node clients/web/gateway.js --listen "${web}" --server "${dial}" &
  pids+=($!)
fi

cli=./build/default/clients/cli/tessera
cat <<MSG

tesserad is starting on ${listen} with the built-in scene "demo".
$( [[ -n $web ]] && echo "The web viewer: http://${web}/" )
In another shell:
  ${cli} --server ${dial} info
  ${cli} --server ${dial} render --scene demo -o out/demo.jpg
  ${cli} --server ${dial} upload ../shared/assets/DamagedHelmet/glTF-Binary/DamagedHelmet.glb
  ${cli} --server ${dial} stream --scene demo --frames 30 --orbit
  ${cli} --server ${dial} bench
Stop with Ctrl-C (or SIGTERM).

MSG
# Whichever stops first (or a signal) stops the other.
wait -n
