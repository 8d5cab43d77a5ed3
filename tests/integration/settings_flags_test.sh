#!/usr/bin/env bash
# The settings flags of both tools come from the settings table (renderer/settings_table.h):
# each tool's --help lists them, both accept every form and refuse bad values with the same
# message naming the flag (exit 2), before any device or server is touched.
# Usage: settings_flags_test.sh TESSERA TESSERA_RENDER
set -euo pipefail
tessera=$1 render=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$render" --help > "$work/render_help"
"$tessera" render --help > "$work/tessera_help"
for flag in --width --aa --samples --culling '--\[no-\]scene-lights' --lights --light-seed \
    --tile-size --light-radius '--\[no-\]animate-lights' --light-time '--\[no-\]shadows' \
    --shadow-atlas --shadow-lights '--\[no-\]shadow-cache' --ssao-radius --ssao-full-res \
    --bloom-strength --auto-exposure --exposure --tonemapper --debug --quality --chroma; do
  grep -q -- "^  $flag " "$work/render_help" || fail "tessera-render --help lacks $flag"
  grep -q -- "^  $flag " "$work/tessera_help" || fail "tessera render --help lacks $flag"
done

# Bad values: the same message from both tools, exit 2.
check_bad() {
  local want=$1; shift
  set +e
  "$render" "$@" > /dev/null 2> "$work/err"; local rc=$?
  set -e
  [[ $rc -eq 2 ]] || fail "tessera-render $* exited $rc"
  grep -qF -- "$want" "$work/err" || fail "tessera-render $*: $(cat "$work/err")"
  set +e
  "$tessera" --server 127.0.0.1:1 render --scene demo -o "$work/x.jpg" "$@" > /dev/null 2> "$work/err"
  rc=$?
  set -e
  [[ $rc -eq 2 ]] || fail "tessera render $* exited $rc"
  grep -qF -- "$want" "$work/err" || fail "tessera render $*: $(cat "$work/err")"
}
check_bad "--aa: 'bogus' is not one of none|msaa|fxaa|taa|vis_mlaa" --aa bogus
check_bad "--width: not a non-negative integer: 'wide'" --width wide
check_bad "--exposure: not a number: 'x'" --exposure x
check_bad "--chroma wants 420 or 444" --chroma 422
check_bad "--light-radius wants MIN,MAX, got '3'" --light-radius 3
check_bad "--debug: 'sky' is not one of none|normals|depth" --debug sky

# Good values of every form get past parsing: tessera then fails to reach the (absent) server,
# exit 1, not a usage error.
set +e
"$tessera" --server 127.0.0.1:1 render --scene demo -o "$work/x.jpg" --width 64 --aa msaa \
  --samples 2 --no-scene-lights --lights 8 --light-seed 3 --tile-size 8 --light-radius 0.1,0.5 \
  --animate-lights --light-time 2 --no-light-culling --no-tile-depth-mask --shadows \
  --shadow-atlas 1024 --shadow-lights 2 --no-shadow-cache --ssao --ssao-radius 0.2 \
  --ssao-strength 2 --ssao-full-res --bloom --bloom-strength 0.2 --ibl --auto-exposure \
  --exposure 1 --tonemapper photographic --debug normals --quality 70 --chroma 444 \
  > /dev/null 2> "$work/err"
rc=$?
set -e
[[ $rc -eq 1 ]] || fail "tessera render with every settings flag exited $rc: $(cat "$work/err")"
echo "settings flags: ok"
