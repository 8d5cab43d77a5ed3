#!/usr/bin/env bash
# Installs dependencies, then
#  1. builds with the asan preset (ASan + UBSan, LeakSanitizer on) and runs every test labelled
#     `asan`: the parsers of client input (glTF, images, requests, with the fuzz regression
#     cases) and every RPC handler (the in-process server, service, job and video tests);
#  2. fuzzes each libFuzzer target for $FUZZ_SECONDS (30) on its corpus (tests/fuzz/run.sh);
#  3. builds everything with the default preset (RelWithDebInfo) and runs every test with ctest,
#     the web viewer's too (its Node packages come from clients/web/package-lock.json, `npm ci`)
#     and the glTF-Validator agreement (tests/gltf/package-lock.json).
# Used by .ci/run.
set -euo pipefail
cd "$(dirname "$0")/.."

./deploy/install-deps.sh
jobs=$(nproc)
export TESSERA_ASSETS_DIR="${TESSERA_ASSETS_DIR:-$PWD/../shared/assets}"

# 1. Under sanitizers. A leak, an ASan report or a UBSan report fails the test that hit it.
cmake --preset asan
cmake --build --preset asan -j "$jobs" --target scene_tests image_tests renderer_unit_tests \
  server_unit_tests server_integration_tests service_integration_tests job_integration_tests \
  video_integration_tests \
  fuzz_gltf fuzz_image fuzz_request tesserad tessera-test-dying-client
ASAN_OPTIONS=detect_leaks=1:abort_on_error=0 \
  LSAN_OPTIONS="suppressions=$PWD/tests/lsan.supp:print_suppressions=0" \
  UBSAN_OPTIONS=print_stacktrace=1 \
  ctest --preset asan -L asan -j "$jobs"

# 2. Fuzzing, bounded.
FUZZ_SECONDS="${FUZZ_SECONDS:-30}" tests/fuzz/run.sh

# 3. Everything, with Vulkan validation layers on for the render tests.
(cd clients/web && npm ci --no-audit --no-fund --loglevel=error)
(cd tests/gltf && npm ci --no-audit --no-fund --loglevel=error)  # the glTF-Validator, test-only
cmake --preset default
cmake --build --preset default -j "$jobs"
ctest --preset default -j "$jobs"
