#!/usr/bin/env bash
# Installs dependencies, builds the render tool and renders the built-in demo scene to
# out/demo.jpg, printing the GPU time of every pass. Extra arguments go to tessera-render
# (e.g. ./deploy/run.sh --scene ../shared/assets/Sponza/glTF/Sponza.gltf --out out/sponza.jpg).
set -euo pipefail
cd "$(dirname "$0")/.."

./deploy/install-deps.sh
cmake --preset default >/dev/null
cmake --build --preset default -j "$(nproc)" --target tessera-render
mkdir -p out
args=("$@")
if [[ ${#args[@]} -eq 0 ]]; then args=(--out out/demo.jpg); fi
./build/default/clients/cli/tessera-render "${args[@]}"
