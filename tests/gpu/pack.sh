#!/usr/bin/env bash
# Packs the renderer's binaries alone for a GPU machine, with ../shared/tools/gpu-pack.sh (its
# .gpu/payload.tar.xz and .gpu/run-on-gpu.sh; add .gpu/ to .git/info/exclude). That tool packs
# every binary it names with their shared libraries: with the daemon and the CLI (gRPC, FFmpeg,
# librsvg, ICU) the payload came to 92 MB, over the device tool's 64 MiB. These are what
# tests/gpu/check.sh runs: tessera-render, tessera-bench, tessera-aa-quality and the render, aa,
# culling, forward+ and lighting tests.
#
# usage (from the project root, after `cmake --build --preset default`):
#   tests/gpu/pack.sh [BUILD_DIR]        (default build/default)
set -euo pipefail
build=$(realpath "${1:-build/default}")
view=$(mktemp -d)
trap 'rm -rf "$view"' EXIT
for b in clients/cli/tessera-render tests/tessera-bench tests/tessera-aa-quality \
         tests/render_tests tests/aa_tests tests/culling_tests tests/forward_plus_tests \
         tests/lighting_tests; do
  [[ -x $build/$b ]] || { echo "pack.sh: $build/$b is not built" >&2; exit 2; }
  mkdir -p "$view/$(dirname "$b")"
  ln -s "$build/$b" "$view/$b"
done
../shared/tools/gpu-pack.sh "$view"
