#!/usr/bin/env bash
# tessera-render says what ran: --json lists every setting as the frame ran it (what `auto`
# chose on this device, what was asked for as asked) and which settings were left at auto, and
# the table output names each `auto` choice. The demo scene at 64x48, on whatever device runs
# it (one without the visibility buffer renders vis_mlaa as msaa, with a note).
# Usage: render_tool_test.sh TESSERA_RENDER
set -euo pipefail
render=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$render" --json --width 64 --height 48 --out "$work/plain.png" > "$work/plain.json"
"$render" --json --width 64 --height 48 --aa vis_mlaa --out "$work/a.png" > "$work/auto.json"
"$render" --json --width 64 --height 48 --aa vis_mlaa --vis-mlaa-coverage analytic \
  --pipeline forward --light-time 1234.5678 --out "$work/b.png" > "$work/asked.json"
python3 - "$work/plain.json" "$work/auto.json" "$work/asked.json" <<'PY' || fail "--json"
import json, sys
plain, auto, asked = (json.load(open(f)) for f in sys.argv[1:])
cpu = plain["device"]["type"] == "cpu"
p = plain["settings"]
assert p["width"] == 64 and p["height"] == 48, p
# What auto chose on this device (README: forward, fragment post passes and CPU light binning
# on CPU devices; the visibility pipeline, compute and GPU binning on GPUs that have it).
vis_buffer = not any(n["field"] == "aa" for n in auto["notes"])
assert p["pipeline"] == ("forward" if cpu or not vis_buffer else "visibility"), p
assert p["post_stage"] == ("fragment" if cpu else "compute"), p
assert p["light_binning"] == ("cpu" if cpu else "gpu"), p
assert sorted(plain["auto"]) == ["light_binning", "pipeline", "post_stage"], plain["auto"]
assert isinstance(p["bloom"], bool) and p["bloom_strength"] == 0.05, p
assert p["animation"] == "", p
s = auto["settings"]
if vis_buffer:
    assert s["aa"] == "vis_mlaa" and s["pipeline"] == "visibility", s
    assert s["vis_mlaa_coverage"] == ("raster" if cpu else "analytic"), s
    assert "vis_mlaa_coverage" in auto["auto"], auto["auto"]
else:  # rendered with msaa, which shades forward
    assert s["aa"] == "msaa" and s["pipeline"] == "forward", s
    assert "vis_mlaa_coverage" not in auto["auto"], auto["auto"]
a = asked["settings"]
# The float asked for, to its last digit (1234.5677: the float nearest 1234.5678), not six digits.
assert abs(a["light_time"] - 1234.5678) < 2e-4, a["light_time"]
assert "pipeline" not in asked["auto"] and "vis_mlaa_coverage" not in asked["auto"], asked["auto"]
if vis_buffer:
    assert a["vis_mlaa_coverage"] == "analytic", a
    assert a["pipeline"] == "visibility", a   # vis_mlaa shades its visibility buffer ...
    assert any(n["field"] == "pipeline" for n in asked["notes"]), asked["notes"]  # ... and says so
PY
"$render" --width 64 --height 48 --out "$work/c.png" > "$work/table"
grep -Eq "^auto: light_binning (cpu|gpu), pipeline (forward|visibility), post_stage (fragment|compute)$" \
  "$work/table" || fail "no auto line: $(cat "$work/table")"
"$render" --width 64 --height 48 --pipeline forward --out "$work/d.png" > "$work/table2"
if grep -q "^auto: .*pipeline" "$work/table2"; then
  fail "an explicit pipeline listed as auto: $(cat "$work/table2")"
fi
echo "render tool: ok"
