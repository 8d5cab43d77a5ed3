#!/usr/bin/env bash
# Live viewing across replicas from the CLI: three tesserad processes sharing a scene store
# (--scene_store_dir), a scene uploaded through one of them, `tessera stream --servers` placed on
# a replica and that replica killed (SIGKILL) mid-stream. The session must reopen on another
# replica with the same scene and orbit, get every frame it asked for, and say so in --json.
# Prints the time from the kill to the first frame on the new replica as a JSON line. The scene
# is uploaded through the first replica and the session placed on the other two, so both the
# session and its move load it from the store.
# Usage: stream_failover_test.sh TESSERAD TESSERA ASSETS_DIR [GLTF (under ASSETS_DIR) [W H]]
set -euo pipefail
tesserad=$1 tessera=$2 assets=$3 gltf=${4:-Box/glTF/Box.gltf} width=${5:-160} height=${6:-120}
# shellcheck source=daemon.sh
source "$(dirname "$0")/daemon.sh"
start_replicas 3 "$tesserad" --scene_store_dir="$work/store"

"$tessera" --server "${ports[0]}" upload "$assets/$gltf" \
  > "$work/upload.txt" 2>&1 || fail "upload: $(cat "$work/upload.txt")"
scene=$(ls "$work/store")
[[ ${#scene} -eq 64 ]] || fail "the store does not hold the scene: $(ls -a "$work/store")"

# Only the replicas that have not loaded the scene: the session and its move both load it from
# the store.
"$tessera" --json stream --servers "${ports[1]},${ports[2]}" --scene "$scene" --frames 80 --orbit --fps 20 \
  --width "$width" --height "$height" > "$work/stream.json" 2> "$work/stream.err" &
client=$!
for _ in $(seq 600); do grep -q "stream: on " "$work/stream.err" && break; sleep 0.05; done
placed=$(sed -n 's/.*stream: on //p' "$work/stream.err" | head -1)
victim=-1
for i in 1 2; do [[ ${ports[$i]} == "$placed" ]] && victim=$i; done
((victim >= 0)) || fail "no placement reported: $(cat "$work/stream.err")"
# Some frames from the first replica (it may load the scene from the store first).
for _ in $(seq 600); do
  n=$("$tessera" --server "$placed" --json info 2>/dev/null |
      python3 -c 'import json, sys; print(json.load(sys.stdin)["frames_rendered"])' || echo 0)
  ((n >= 5)) && break
  sleep 0.1
done
kill -KILL "${pids[$victim]}"
wait "$client" || fail "the stream failed: $(cat "$work/stream.err") $(cat "$work/stream.json")"

python3 - "$work/stream.json" "$placed" "${ports[0]}" "$gltf" <<'PY' || fail "stream --json: $(cat "$work/stream.json" | head -c 2000)"
import json, sys
d = json.load(open(sys.argv[1]))
placed = sys.argv[2]
assert d["frames"] == 80, d["frames"]
assert d["server"] == placed, d["server"]
f = d["failovers"]
assert len(f) == 1, f
f = f[0]
assert f["from"] == placed and f["to"] and f["to"] != placed and f["to"] != sys.argv[3], f
assert f["error"]["code"] == "UNAVAILABLE", f
assert 0 < f["frames_before"] < 80, f
assert f["first_frame_ms"] is not None and f["first_frame_ms"] < 5000, f
# The orbit went on where it was: the first frame after the move is not the orbit's start.
frames = d["frame_list"]
before, after = frames[f["frames_before"] - 1], frames[f["frames_before"]]
assert after["scene_id"] == before["scene_id"], (before["scene_id"], after["scene_id"])
assert after["camera"]["eye"] != frames[0]["camera"]["eye"], "the orbit restarted"
print(json.dumps({"failover_first_frame_ms": round(f["first_frame_ms"], 1), "scene": sys.argv[4],
                  "size": "%dx%d" % (after["width"], after["height"]), "from": f["from"],
                  "to": f["to"]}))
PY
grep -q "lost (.*); reopened on" "$work/stream.err" || fail "no word of the failover: $(cat "$work/stream.err")"
