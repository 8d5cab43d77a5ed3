#!/usr/bin/env bash
# Live viewing across replicas from the CLI: three tesserad processes sharing a scene store
# (--scene_store_dir), a scene uploaded through one of them, `tessera stream --servers` placed on
# a replica and that replica killed (SIGKILL) mid-stream. The session must reopen on another
# replica with the same scene and orbit, get every frame it asked for, and say so in --json.
# Usage: stream_failover_test.sh TESSERAD TESSERA ASSETS_DIR
set -euo pipefail
tesserad=$1 tessera=$2 assets=$3
# shellcheck source=daemon.sh
source "$(dirname "$0")/daemon.sh"
start_replicas 3 "$tesserad" --scene_store_dir="$work/store"

"$tessera" --server "${ports[0]}" upload "$assets/Box/glTF/Box.gltf" \
  > "$work/upload.txt" 2>&1 || fail "upload: $(cat "$work/upload.txt")"
scene=$(ls "$work/store")
[[ ${#scene} -eq 64 ]] || fail "the store does not hold the scene: $(ls -a "$work/store")"

"$tessera" --json stream --servers "$servers" --scene "$scene" --frames 80 --orbit --fps 20 \
  --width 160 --height 120 > "$work/stream.json" 2> "$work/stream.err" &
client=$!
for _ in $(seq 600); do grep -q "stream: on " "$work/stream.err" && break; sleep 0.05; done
placed=$(sed -n 's/.*stream: on //p' "$work/stream.err" | head -1)
victim=-1
for i in 0 1 2; do [[ ${ports[$i]} == "$placed" ]] && victim=$i; done
((victim >= 0)) || fail "no placement reported: $(cat "$work/stream.err")"
sleep 1  # some frames from the first replica
kill -KILL "${pids[$victim]}"
wait "$client" || fail "the stream failed: $(cat "$work/stream.err") $(cat "$work/stream.json")"

python3 - "$work/stream.json" "$placed" <<'PY' || fail "stream --json: $(cat "$work/stream.json" | head -c 2000)"
import json, sys
d = json.load(open(sys.argv[1]))
placed = sys.argv[2]
assert d["frames"] == 80, d["frames"]
assert d["server"] == placed, d["server"]
f = d["failovers"]
assert len(f) == 1, f
f = f[0]
assert f["from"] == placed and f["to"] and f["to"] != placed, f
assert f["error"]["code"] == "UNAVAILABLE", f
assert 0 < f["frames_before"] < 80, f
assert f["first_frame_ms"] is not None and f["first_frame_ms"] < 5000, f
# The orbit went on where it was: the first frame after the move is not the orbit's start.
frames = d["frame_list"]
before, after = frames[f["frames_before"] - 1], frames[f["frames_before"]]
assert after["scene_id"] == before["scene_id"], (before["scene_id"], after["scene_id"])
assert after["camera"]["eye"] != frames[0]["camera"]["eye"], "the orbit restarted"
print("failover: %.0f ms from the loss to the first frame on %s" % (f["first_frame_ms"], f["to"]))
PY
grep -q "lost (.*); reopened on" "$work/stream.err" || fail "no word of the failover: $(cat "$work/stream.err")"
