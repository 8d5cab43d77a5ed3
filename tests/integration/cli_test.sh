#!/usr/bin/env bash
# The tessera CLI against a real tesserad, as a user (or a script) runs it: exit codes, --json
# output, files written, and the server's messages on errors.
# Usage: cli_test.sh TESSERAD TESSERA ASSETS_DIR
set -euo pipefail
tesserad=$1 tessera=$2 assets=$3
# shellcheck source=daemon.sh
source "$(dirname "$0")/daemon.sh"
# Runs tessera with stdout in $work/out and stderr in $work/err; its exit status in $rc.
run() { set +e; "$tessera" "$@" > "$work/out" 2> "$work/err"; rc=$?; set -e; }
# Checks that $work/out is exactly one JSON document d for which the Python expression $1 holds.
json_is() {
  python3 -c 'import json, sys; d = json.load(open(sys.argv[1])); assert eval(sys.argv[2]), d' \
    "$work/out" "$1" || fail "$2: $(head -c 600 "$work/out")"
}

start_tesserad "$tesserad"

# TLS asked of a plaintext daemon: one message from the CLI, no gRPC log lines before it.
run --tls info
[[ $rc -ne 0 ]] || fail "--tls against a plaintext daemon succeeded"
grep -q "does it speak TLS" "$work/err" || fail "--tls message: $(cat "$work/err")"
! grep -q "ssl_transport_security\|\.cc:[0-9]" "$work/err" || fail "gRPC's log leaked: $(cat "$work/err")"
[[ $(wc -l < "$work/err") -eq 1 ]] || fail "--tls: more than one line: $(cat "$work/err")"

"$tessera" --json info > "$work/info.json"
python3 - "$work/info.json" <<'PY' || fail "info --json"
import json, sys
d = json.load(open(sys.argv[1]))
assert d["version"] and d["device"]["name"], d
# Every fallback names what the device lacks and what runs instead (SwiftShader has several).
assert all(f["missing"] and f["path"] for f in d["device"].get("fallbacks", [])), d["device"]
if "SwiftShader" in d["device"]["name"]:
    missing = [f["missing"] for f in d["device"]["fallbacks"]]
    assert "drawIndirectCount" in missing, missing
PY

# Upload prints the id alone on stdout; a second upload is skipped and gives the same id.
id=$("$tessera" upload "$assets/Box/glTF-Binary/Box.glb" 2>/dev/null)
[[ $id =~ ^[0-9a-f]{64}$ ]] || fail "upload printed '$id'"
again=$("$tessera" upload "$assets/Box/glTF-Binary/Box.glb" 2>"$work/again.err")
[[ $again == "$id" ]] || fail "re-upload gave '$again'"
grep -q "already on the server" "$work/again.err" || fail "re-upload was not skipped"

"$tessera" scenes | grep -q "${id:0:12}" || fail "scenes does not list the upload"

# A file the server refuses: the error names the path given and the field, the file once.
python3 - "$assets/Box/glTF/Box.gltf" "$work/bad.gltf" <<'PY'
import json, shutil, sys, os
d = json.load(open(sys.argv[1]))
d["materials"][0]["pbrMetallicRoughness"]["metallicFactor"] = 2
json.dump(d, open(sys.argv[2], "w"))
shutil.copy(os.path.join(os.path.dirname(sys.argv[1]), "Box0.bin"), os.path.dirname(sys.argv[2]))
PY
run upload "$work/bad.gltf"
[[ $rc -ne 0 ]] || fail "a bad upload succeeded"
grep -q "INVALID_ARGUMENT: $work/bad.gltf: materials\[0\].pbrMetallicRoughness.metallicFactor: 2 is out of range" \
  "$work/err" || fail "bad upload: $(cat "$work/err")"

"$tessera" render --scene "${id:0:12}" --width 96 --height 64 -o "$work/box.png" > /dev/null
python3 - "$work/box.png" <<'PY' || fail "render did not write a 96x64 PNG"
import struct, sys
b = open(sys.argv[1], "rb").read()
assert b[:8] == b"\x89PNG\r\n\x1a\n"
w, h = struct.unpack(">II", b[16:24])
assert (w, h) == (96, 64), (w, h)
PY

# The frame's settings line says what the server's auto chose (how vis_mlaa found its samples,
# the pipeline, where the post passes ran, where the lights were binned).
"$tessera" render --scene demo --width 64 --height 48 --aa vis_mlaa -o "$work/vis.png" \
  > "$work/vis.txt"
tr -d '\n' < "$work/vis.txt" | tr -s ' ' |
  grep -Eq "aa (vis_mlaa x[0-9]+ \((raster|analytic) coverage\)|msaa x[0-9]+), .*pipeline (visibility|forward), post passes (fragment|compute), light binning (cpu|gpu)" ||
  fail "render's settings line lacks what auto chose: $(cat "$work/vis.txt")"

"$tessera" --json stream --scene demo --frames 3 --orbit --width 64 --height 48 \
  --save "$work/frames" > "$work/stream.json"
[[ $(ls "$work/frames" | wc -l) -eq 3 ]] || fail "stream --save did not write 3 frames"
python3 - "$work/stream.json" <<'PY' || fail "stream --json"
import json, sys
d = json.load(open(sys.argv[1]))
assert d["frames"] == 3, d
PY

# bench: one table row per configuration, and with --json the full figures of each.
"$tessera" bench --suite lights --width 64 --height 48 --frames 3 --warmup 1 > "$work/bench.txt"
python3 - "$work/bench.txt" <<'PY' || fail "bench table: $(cat "$work/bench.txt")"
import sys
lines = open(sys.argv[1]).read().splitlines()
assert lines[0].startswith("tesserad ") and ", device " in lines[0], lines[0]
assert any(l.startswith("timing ") for l in lines), lines
head = next(i for i, l in enumerate(lines) if l.startswith("config"))
assert "fps" in lines[head] and "lat p95" in lines[head], lines[head]
rows = [l.split() for l in lines[head + 1:head + 5]]
assert [r[:2] for r in rows] == [["lights", n] for n in ("0", "64", "256", "1024")], rows
assert all(float(r[2]) > 0 for r in rows), rows  # fps
PY
"$tessera" --json bench --suite aa --width 64 --height 48 --frames 3 --warmup 1 > "$work/out"
python3 - "$work/out" "$work/info.json" <<'PY' || fail "bench --json: $(head -c 600 "$work/out")"
import json, sys
d = json.load(open(sys.argv[1]))
offered = json.load(open(sys.argv[2]))["choices"]["aa"]
assert d["device"]["name"] and d["suite"] == "aa" and d["failed"] == 0, d
assert [r["config"] for r in d["results"]] == ["aa " + m for m in offered], d["results"]
for r in d["results"]:
    assert r["ok"] and r["frames"] == 3 and r["fps"] > 0 and r["bytes_median"] > 0, r
    # A mode the device cannot run (vis_mlaa without the visibility buffer) falls back with a note.
    assert r["settings"]["aa"] == r["setting"]["aa"] or any(
        n["field"] == "aa" for n in r["notes"]), r
    assert r["gpu_total_median_ms"] > 0 and r["pass_median_ms"], r
    lat = r["latency_ms"]
    assert lat["events"] == 3 and 0 < lat["median"] <= lat["p95"], lat
    assert r["timing_source"] in ("gpu_timestamps", "pass_wall_clock", "frame_wall_clock"), r
PY
# With --codec h264 every configuration is a video session: bitrate and keyframes per row.
"$tessera" --json bench --suite lights --codec h264 --crf 30 --width 64 --height 48 --frames 3 \
  --warmup 1 > "$work/out"
json_is 'all(r["ok"] and r["codec"].startswith("avc1.") and r["bitrate_kbps"] > 0 for r in d["results"])' \
  "bench --codec h264"
# A configuration that fails is reported in its row; the others still run; exit 1.
run bench --suite culling --samples 3 --width 64 --height 48 --frames 2 --warmup 0
[[ $rc -eq 1 ]] || fail "bench with failing configurations exited $rc"
[[ $(grep -c "FAILED  INVALID_ARGUMENT: settings.samples" "$work/out") -eq 4 ]] ||
  fail "bench rows: $(cat "$work/out")"
run --json bench --suite culling --samples 3 --width 64 --height 48 --frames 2
[[ $rc -eq 1 ]] || fail "bench --json with failing configurations exited $rc"
json_is 'd["failed"] == 4 and all(r["error"]["code"] == "INVALID_ARGUMENT" for r in d["results"])' \
  "bench --json failed rows"

# --json: one JSON document on stdout on every path, errors included; the exit codes.
run --json scenes
[[ $rc -eq 0 ]] || fail "scenes --json exited $rc"
json_is 'any(s["scene_id"] == "demo" for s in d["scenes"])' "scenes --json"
run --json render --scene no-such-scene -o "$work/x.jpg"
[[ $rc -eq 1 ]] || fail "render --json of an unknown scene exited $rc"
json_is 'd["error"]["code"] == "NOT_FOUND" and "no-such-scene" in d["error"]["message"]' \
  "render --json error"
grep -q "NOT_FOUND" "$work/err" || fail "render --json error not on stderr: $(cat "$work/err")"
run --json rm no-such-scene
[[ $rc -eq 1 ]] || fail "rm --json of an unknown scene exited $rc"
json_is 'd[0]["scene_id"] == "no-such-scene" and d[0]["error"]["code"] == "NOT_FOUND"' \
  "rm --json error"
run --json stream --scene no-such-scene --frames 2
[[ $rc -eq 1 ]] || fail "stream --json of an unknown scene exited $rc"
json_is 'd["error"]["code"] == "NOT_FOUND"' "stream --json error"
run --json render --bogus-flag
[[ $rc -eq 2 ]] || fail "a bad render command line exited $rc, not 2"
json_is 'd["error"]["code"] == "USAGE" and "--bogus-flag" in d["error"]["message"]' "usage --json"
run --json no-such-command
[[ $rc -eq 2 ]] || fail "an unknown command exited $rc, not 2"
json_is 'd["error"]["code"] == "USAGE"' "unknown command --json"
run --json --server 127.0.0.1:1 info
[[ $rc -eq 1 ]] || fail "info against a closed port exited $rc"
json_is 'd["error"]["code"] == "UNAVAILABLE"' "connect failure --json"

# Errors: non-zero exit and the server's code and message.
if "$tessera" render --scene no-such-scene -o "$work/x.jpg" 2> "$work/err"; then
  fail "render of an unknown scene succeeded"
fi
grep -q "NOT_FOUND" "$work/err" || fail "no NOT_FOUND in: $(cat "$work/err")"
if "$tessera" render --scene demo --width 0 -o "$work/x.jpg" 2> "$work/err"; then
  fail "width 0 succeeded"
fi
grep -q "settings.width" "$work/err" || fail "message does not name settings.width"

"$tessera" rm "$id" > /dev/null
if "$tessera" scenes | grep -q "${id:0:12}"; then fail "rm left the scene"; fi

# Idle refinement: an orbit with --interactive gets frames rendered at half size.
"$tessera" --json stream --scene demo --frames 4 --orbit --width 96 --height 64 \
  --interactive 0.5 > "$work/interactive.json"
python3 - "$work/interactive.json" <<'PY' || fail "stream --interactive"
import json, sys
d = json.load(open(sys.argv[1]))
moving = [f for f in d["frame_list"] if f["profile"] == "interactive"]
assert moving, [f["profile"] for f in d["frame_list"]]
assert all(f["render_width"] == 48 and f["width"] == 96 for f in moving), moving
PY

# H.264: an orbit as one video, saved as .mp4 and as a raw .h264 stream; the sizes and
# keyframes in --json; a video file without --codec h264, and odd sizes, are refused.
"$tessera" --json stream --scene demo --frames 5 --orbit --width 96 --height 64 --codec h264 \
  --crf 20 --save "$work/video/orbit.mp4" > "$work/h264.json"
python3 - "$work/h264.json" "$work/video/orbit.mp4" <<'PY' || fail "stream --codec h264"
import json, sys
d = json.load(open(sys.argv[1]))
frames = d["frame_list"]
assert [f["encoding"] for f in frames] == ["h264"] * 5, [f["encoding"] for f in frames]
assert frames[0]["keyframe"] and not any(f.get("keyframe") for f in frames[1:]), frames
assert d["keyframes"] == 1 and d["codec"].startswith("avc1."), d
assert d["bitrate_kbps"] > 0 and d["bytes_total"] == sum(f["bytes"] for f in frames), d
mp4 = open(sys.argv[2], "rb").read()
assert mp4[4:8] == b"ftyp" and b"avcC" in mp4 and b"moov" in mp4, mp4[:16]
PY
"$tessera" stream --scene demo --frames 3 --width 96 --height 64 --codec h264 \
  --save "$work/raw.h264" > "$work/h264.txt"
head -c 5 "$work/raw.h264" | od -An -tx1 | grep -q "00 00 00 01" || fail "raw.h264 is not Annex B"
grep -q "avc1\..*1 keyframes" "$work/h264.txt" || fail "stream summary: $(cat "$work/h264.txt")"
run stream --scene demo --frames 2 --save "$work/x.mp4"
[[ $rc -eq 2 ]] && grep -q "needs --codec h264" "$work/err" || fail "mp4 without h264: $rc $(cat "$work/err")"
run stream --scene demo --frames 2 --codec h264 --save "$work/h264frames"
[[ $rc -eq 2 ]] && grep -q "save to FILE.mp4 or FILE.h264" "$work/err" ||
  fail "h264 into a directory: $rc $(cat "$work/err")"
run stream --scene demo --frames 2 --codec h264 --width 97 --height 64
[[ $rc -eq 1 ]] && grep -q "INVALID_ARGUMENT: open.settings.width: 97" "$work/err" ||
  fail "odd h264 width: $rc $(cat "$work/err")"
run stream --scene demo --frames 2 --codec h264 --crf 99
grep -q "open.video.crf: 99 is out of range" "$work/err" || fail "crf 99: $(cat "$work/err")"

# Jobs: submit (watched to the end, fetched into --out), list, a keyframe path, fetch, cancel
# and rm, and the exit codes.
"$tessera" --json job submit --scene demo --frames 0..3 --orbit --width 64 --height 48 --png \
  --name cli-orbit --out "$work/job" > "$work/job.json"
python3 - "$work/job.json" "$work/job" <<'PY' || fail "job submit --json"
import json, os, sys
d = json.load(open(sys.argv[1]))
assert d["job"]["state"] == "succeeded", d["job"]
assert d["job"]["spec"]["output"] == "return", d["job"]
assert d["job"]["frames_done"] == 4, d["job"]
assert len(d["frames"]) == 4 and len(d["files"]) == 4, d
assert sorted(os.listdir(sys.argv[2])) == ["frame_%05d.png" % i for i in range(4)]
PY
job_id=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["job"]["job_id"])' \
  "$work/job.json")
"$tessera" job list | grep -q "$job_id.*succeeded.*cli-orbit" || fail "job list"
cat > "$work/keys.json" <<'JSON'
{"interpolation": "catmull_rom", "keyframes": [
  {"frame": 0, "eye": [0, 1, 4], "target": [0, 0, 0]},
  {"frame": 4, "eye": [4, 1, 0], "target": [0, 0, 0], "yfov": 0.6}]}
JSON
kid=$("$tessera" job submit --scene demo --frames 0..4:2 --keyframes "$work/keys.json" \
  --width 64 --height 48 --pattern "k_%02d.jpg" --detach 2>/dev/null)
[[ $kid =~ ^[0-9a-f]{16}$ ]] || fail "job submit --detach printed '$kid'"
"$tessera" job watch "$kid" 2> /dev/null || fail "job watch of the keyframe job"
"$tessera" job fetch "$kid" --out "$work/kf" 2> /dev/null || fail "job fetch"
[[ -f $work/kf/k_00.jpg && -f $work/kf/k_02.jpg && -f $work/kf/k_04.jpg ]] ||
  fail "job fetch wrote: $(ls "$work/kf")"
big=$("$tessera" job submit --scene demo --frames 0..99999 --width 32 --height 32 --detach \
  2>/dev/null)
"$tessera" job cancel "$big" 2>&1 | grep -q "cancelled" || fail "job cancel"
# A job that ended cancelled: exit 3 from watch, with the Job in the --json document.
run --json job watch "$big"
[[ $rc -eq 3 ]] || fail "job watch of a cancelled job exited $rc, not 3"
json_is 'd["job"]["state"] == "cancelled"' "job watch --json of a cancelled job"
"$tessera" job rm "$big" 2> /dev/null || fail "job rm"
if "$tessera" job list | grep -q "$big"; then fail "job rm left the job"; fi
if "$tessera" job submit --scene demo --frames 9..1 2> "$work/err"; then
  fail "a backwards frame range succeeded"
fi
grep -q "spec.frames.last" "$work/err" || fail "no spec.frames.last in: $(cat "$work/err")"
set +e
"$tessera" job submit --frames 0..1 --bogus-flag > /dev/null 2>&1
rc=$?
set -e
[[ $rc -eq 2 ]] || fail "a bad job command line exited $rc, not 2"

kill -TERM "$pid"
wait "$pid" || fail "tesserad exited with $? after SIGTERM"
pid=""

# A daemon that requires a bearer token: refused without it (exit 1, UNAUTHENTICATED), served
# with --token-file or $TESSERA_TOKEN.
echo "cli-test-token-0123456789 cli" > "$work/tokens"
echo "cli-test-token-0123456789" > "$work/token"
rm -f "$work/port"
"$tesserad" --listen=127.0.0.1:0 --port_file="$work/port" --log_level=warn \
  --token_file="$work/tokens" &
pid=$!
for _ in $(seq 600); do [[ -s $work/port ]] && break; sleep 0.1; done
[[ -s $work/port ]] || fail "tesserad with tokens did not start"
export TESSERA_SERVER="127.0.0.1:$(cat "$work/port")"
if "$tessera" info > /dev/null 2> "$work/err"; then fail "info without a token succeeded"; fi
grep -q "UNAUTHENTICATED" "$work/err" || fail "no UNAUTHENTICATED in: $(cat "$work/err")"
"$tessera" --token-file "$work/token" info | grep -q "bearer tokens required" ||
  fail "info with --token-file"
TESSERA_TOKEN=cli-test-token-0123456789 "$tessera" render --scene demo --width 32 --height 24 \
  -o "$work/token.jpg" > /dev/null || fail "render with \$TESSERA_TOKEN"

kill -TERM "$pid"
wait "$pid" || fail "tesserad exited with $? after SIGTERM"
pid=""
echo "cli_test: OK"
