#!/usr/bin/env bash
# Installs dependencies, builds with the default preset (RelWithDebInfo) and runs every test.
# Then builds the CPU-only parsers with the asan preset (ASan + UBSan) and runs their tests,
# malformed inputs included. Used by .ci/run. About 10 minutes on 2 cores from scratch.
set -euo pipefail
cd "$(dirname "$0")/.."

./deploy/install-deps.sh
jobs=$(nproc)

cmake --preset default
cmake --build --preset default -j "$jobs"
ctest --preset default -j "$jobs"

# Untrusted-input code under sanitizers: the glTF importer and the image codecs.
cmake --preset asan
cmake --build --preset asan -j "$jobs" --target scene_tests image_tests
ctest --preset asan -j "$jobs" -R '^(GltfImport|Malformed|Image|DemoScene)'
