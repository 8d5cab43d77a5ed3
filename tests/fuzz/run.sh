#!/usr/bin/env bash
# Builds the libFuzzer targets (preset `fuzz`: clang, ASan + UBSan) and fuzzes each for a
# bounded time on top of its seed corpus and the committed regression cases.
#
#   tests/fuzz/run.sh                 # 30 s per target (what ./deploy/test.sh runs)
#   FUZZ_SECONDS=3600 tests/fuzz/run.sh fuzz_gltf   # a long run of one target
#
# New inputs that reach new coverage go to build/fuzz/corpus/<target> (kept between runs, not
# committed). A crash, leak, timeout or out-of-memory stops the run with exit status 1 and
# leaves the input in build/fuzz/artifacts/<target>/; fix the bug, then commit the input to
# tests/fuzz/regressions/<kind>/ so the normal tests run it from then on.
set -euo pipefail
cd "$(dirname "$0")/../.."

seconds="${FUZZ_SECONDS:-30}"
targets=("$@")
if ((${#targets[@]} == 0)); then targets=(fuzz_gltf fuzz_image fuzz_request); fi

cmake --preset fuzz >/dev/null
cmake --build --preset fuzz -j "$(nproc)" --target "${targets[@]}"

declare -A kind=([fuzz_gltf]=gltf [fuzz_image]=image [fuzz_request]=request)
declare -A dict=([fuzz_gltf]="-dict=tests/fuzz/gltf.dict")
status=0
for t in "${targets[@]}"; do
  k="${kind[$t]:?unknown target $t}"
  work="build/fuzz/corpus/$t"
  artifacts="build/fuzz/artifacts/$t"
  mkdir -p "$work" "$artifacts"
  echo "== $t: ${seconds} s"
  # -rss_limit_mb, -malloc_limit_mb: the targets' own limits keep any input far below them,
  # so reaching one is a bug (an allocation the limits missed, like libpng's chunk buffer before
  # it was capped). -timeout: no single input may take 10 s.
  if ! ASAN_OPTIONS=detect_leaks=1 \
      "build/fuzz/tests/fuzz/$t" -max_total_time="$seconds" -rss_limit_mb=2048 \
      -malloc_limit_mb=512 -timeout=10 \
      -max_len=131072 -print_final_stats=1 -artifact_prefix="$artifacts/" ${dict[$t]:-} \
      "$work" "tests/fuzz/corpus/$k" "tests/fuzz/regressions/$k" 2>"$artifacts/log.txt"; then
    echo "$t FAILED: the input is in $artifacts/ (log: $artifacts/log.txt)"
    grep -E "ERROR|SUMMARY|Test unit written" "$artifacts/log.txt" | head -20 || true
    status=1
  fi
  # The last status line: executions, coverage (cov: edges, ft: features), corpus size.
  grep -E "^#[0-9]+.*(DONE|pulse|NEW|REDUCE)" "$artifacts/log.txt" | tail -1 || true
  grep -E "stat::number_of_executed_units|stat::peak_rss_mb" "$artifacts/log.txt" || true
done
exit "$status"
