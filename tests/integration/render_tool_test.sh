#!/usr/bin/env bash
# tessera-render says what ran: --json lists every setting as the frame ran it (what `auto`
# chose on this device, what was asked for as asked), and the table output names each `auto`
# choice. On the demo scene at 64x48 with vis_mlaa (the device's choices, whatever the device).
# Usage: render_tool_test.sh TESSERA_RENDER
set -euo pipefail
render=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$render" --json --width 64 --height 48 --aa vis_mlaa --out "$work/a.png" > "$work/auto.json"
"$render" --json --width 64 --height 48 --aa vis_mlaa --vis-mlaa-coverage analytic \
  --pipeline forward --out "$work/b.png" > "$work/asked.json"
python3 - "$work/auto.json" "$work/asked.json" <<'PY' || fail "settings in --json"
import json, sys
auto = json.load(open(sys.argv[1]))
asked = json.load(open(sys.argv[2]))
s = auto["settings"]
assert s["width"] == 64 and s["height"] == 48, s
assert s["aa"] == "vis_mlaa" and s["pipeline"] == "visibility", s
cpu = auto["device"]["type"] == "cpu"
for row, choices in (("vis_mlaa_coverage", ("raster", "analytic")), ("post_stage", ("fragment", "compute")),
                     ("light_binning", ("cpu", "gpu"))):
    assert s[row] in choices, (row, s[row])   # auto resolved, never "auto"
assert s["vis_mlaa_coverage"] == ("raster" if cpu else "analytic"), s
assert isinstance(s["bloom"], bool) and s["bloom_strength"] == 0.05, s
a = asked["settings"]
assert a["vis_mlaa_coverage"] == "analytic", a
assert a["pipeline"] == "visibility", a   # vis_mlaa shades its visibility buffer ...
assert any(n["field"] == "pipeline" for n in asked["notes"]), asked["notes"]  # ... and says so
PY
"$render" --width 64 --height 48 --aa vis_mlaa --out "$work/c.png" > "$work/table"
grep -q "^auto: .*vis_mlaa_coverage \(raster\|analytic\)" "$work/table" ||
  fail "no auto line: $(cat "$work/table")"
"$render" --width 64 --height 48 --aa vis_mlaa --vis-mlaa-coverage raster --out "$work/d.png" \
  > "$work/table2"
if grep "^auto: " "$work/table2" | grep -q vis_mlaa_coverage; then
  fail "an explicit vis_mlaa_coverage listed as auto: $(cat "$work/table2")"
fi
echo "render tool: ok"
