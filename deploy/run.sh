#!/usr/bin/env bash
# Installs dependencies, builds tesserad and the tessera CLI, and runs tesserad in the
# foreground with the built-in demo scene (scene id "demo"). Ctrl-C stops it cleanly.
# Extra arguments go to tesserad (e.g. ./deploy/run.sh --listen=0.0.0.0:50051 --max_scenes=8;
# see ./build/default/server/tesserad --help).
set -euo pipefail
cd "$(dirname "$0")/.."

./deploy/install-deps.sh
cmake --preset default >/dev/null
cmake --build --preset default -j "$(nproc)" --target tesserad tessera tessera-render

listen=127.0.0.1:50051
for a in "$@"; do
  case "$a" in --listen=*) listen="${a#--listen=}" ;; esac
done
cat <<MSG

tesserad is starting on ${listen} with the built-in scene "demo". In another shell:
  ./build/default/clients/cli/tessera --server ${listen} info
  ./build/default/clients/cli/tessera --server ${listen} render --scene demo -o out/demo.jpg
  ./build/default/clients/cli/tessera --server ${listen} upload ../shared/assets/DamagedHelmet/glTF-Binary/DamagedHelmet.glb
  ./build/default/clients/cli/tessera --server ${listen} stream --scene demo --frames 30 --orbit
Stop it with Ctrl-C (or SIGTERM).

MSG
mkdir -p out
exec ./build/default/server/tesserad --listen="${listen}" "$@"
