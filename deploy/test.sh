#!/usr/bin/env bash
# Installs dependencies, builds the untrusted-input code (glTF import, image codecs) with the
# asan preset (ASan + UBSan) and runs its tests, then builds everything with the default preset
# (RelWithDebInfo) and runs every test with ctest. Used by .ci/run.
set -euo pipefail
cd "$(dirname "$0")/.."

./deploy/install-deps.sh
jobs=$(nproc)
export TESSERA_ASSETS_DIR="${TESSERA_ASSETS_DIR:-$PWD/../shared/assets}"

# Parsers of untrusted input under sanitizers, malformed inputs included.
cmake --preset asan
cmake --build --preset asan -j "$jobs" --target scene_tests image_tests
./build/asan/tests/image_tests
./build/asan/tests/scene_tests

# Everything, with Vulkan validation layers on for the render tests.
cmake --preset default
cmake --build --preset default -j "$jobs"
ctest --preset default -j "$jobs"
