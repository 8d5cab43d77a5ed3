#!/usr/bin/env bash
# A render farm on loopback: three tesserad processes, a 60-frame job spread over them by
# `tessera job submit --servers` (gRPC round_robin), one daemon killed (SIGKILL) mid-job. Every
# frame must be there once, byte-identical to the same job run on a single daemon as a
# server-side job (SubmitJob), and the killed daemon's frames must have been retried elsewhere.
# Then an animated scene's shot (the skinned cylinder at 12 fps) spread over two daemons, each
# frame byte-identical to the same job on one daemon.
# Usage: farm_test.sh TESSERAD TESSERA ANIMATED_DIR
set -euo pipefail
tesserad=$1 tessera=$2 animated=$3
# shellcheck source=daemon.sh
source "$(dirname "$0")/daemon.sh"
# Info logs: each finished RenderJobFrame is a line, which tells when daemon 1 is serving.
start_replicas 3 "$tesserad" --log_level=info

# Runs job ARGS... on one daemon as a server-side job into DIR and checks its N frames are
# byte-identical to the farm's in FARM_DIR. Usage: same_as_one_daemon PORT DIR FARM_DIR N ARGS...
same_as_one_daemon() {
  local port=$1 dir=$2 farm=$3 n=$4
  shift 4
  "$tessera" --server "$port" "$@" --out "$dir" > /dev/null 2>&1 || fail "the single-daemon job failed"
  for f in "$dir"/*.png; do
    cmp -s "$f" "$farm/$(basename "$f")" || fail "$(basename "$f") differs from the farm's"
  done
  [[ $(find "$dir" -name '*.png' | wc -l) -eq $n ]] || fail "single run: not $n frames"
}

# Slow enough frames (taa accumulates 4 renders each) that every daemon has calls in flight
# when one is killed.
job=(job submit --scene demo --frames 0..59 --orbit --width 320 --height 180 --aa taa
     --taa-frames 4 --png)

"$tessera" --json "${job[@]}" --servers "$servers" --out "$work/farm" > "$work/farm.json" &
client=$!
# Kill daemon 1 once a few frames exist and it has finished one of its own: round_robin keeps
# giving it frames, so it has some in flight then (on a loaded machine a daemon can connect
# late; killed before it served anything, it would have nothing to retry).
for _ in $(seq 600); do
  n=$( (find "$work/farm" -name '*.png' 2>/dev/null || true) | wc -l)
  served=$(grep -c "RenderJobFrame" "$work/log1" 2>/dev/null || true)
  ((n >= 8 && served >= 1)) && break
  sleep 0.05
done
kill -KILL "${pids[1]}"
wait "$client" || fail "the farm job failed: $(cat "$work/farm.json")"

python3 - "$work/farm.json" "${ports[1]}" <<'PY' || fail "farm --json: $(cat "$work/farm.json")"
import json, sys
d = json.load(open(sys.argv[1]))
assert d["frames"] == 60, d
assert d["retried"] >= 1, "no frame was retried after the kill: %s" % d
assert sum(d["servers"].values()) == 60, d
assert len(d["servers"]) >= 2, d
PY
[[ $(find "$work/farm" -name '*.png' | wc -l) -eq 60 ]] || fail "not 60 frames"
[[ -z $(find "$work/farm" -name '*.part') ]] || fail "a partial file was left behind"

# The same job as a server-side job on one surviving daemon.
same_as_one_daemon "${ports[0]}" "$work/single" "$work/farm" 60 "${job[@]}"
echo "farm: 60 frames over 3 daemons with one killed, identical to one daemon's"

# A farm whose second daemon is down at the start (the killed one's port): it starts with the
# daemon that answers, and the second, started mid-job, is found by the probes and takes frames.
"$tessera" --json "${job[@]/0..59/0..79}" --servers "${ports[0]},${ports[1]}" --out "$work/late" \
  > "$work/late.json" 2> "$work/late.err" &
client=$!
for _ in $(seq 600); do
  n=$( (find "$work/late" -name '*.png' 2>/dev/null || true) | wc -l)
  ((n >= 4)) && break
  sleep 0.05
done
grep -q "starting without it" "$work/late.err" || fail "no word of the daemon that is down: $(cat "$work/late.err")"
"$tesserad" --listen="${ports[1]}" --log_level=warn 2> "$work/log_late" &
pids+=($!)
wait "$client" || fail "the farm job with a daemon down failed: $(cat "$work/late.err")"
python3 - "$work/late.json" "${ports[1]}" <<'PY' || fail "late farm --json: $(cat "$work/late.json") $(cat "$work/late.err")"
import json, sys
d = json.load(open(sys.argv[1]))
assert d["frames"] == 80 and sum(d["servers"].values()) == 80, d
assert d["servers_down"] == [], d
assert any(sys.argv[2] in peer for peer in d["servers"]), "the late daemon took no frame: %s" % d
PY
grep -q "answers now" "$work/late.err" || fail "the late daemon was not reported: $(cat "$work/late.err")"
[[ $(find "$work/late" -name '*.png' | wc -l) -eq 80 ]] || fail "late farm: not 80 frames"
echo "farm: started with one of two daemons; the other, started mid-job, took frames"

# An animation: frame n is the skinned cylinder at n / 12 s, rendered by whichever daemon, the
# same bytes as one daemon's server-side job.
shot=(job submit --scene-file "$animated/skinned_cylinder.gltf" --animation bend --fps 12
      --frames 0..23 --width 160 --height 120 --png)
"$tessera" --json "${shot[@]}" --servers "${ports[0]},${ports[1]}" --out "$work/shot_farm" \
  > "$work/shot_farm.json" 2> "$work/shot_farm.err" || fail "the animated farm job failed: $(cat "$work/shot_farm.err")"
python3 - "$work/shot_farm.json" <<'PY' || fail "animated farm --json: $(cat "$work/shot_farm.json")"
import json, sys
d = json.load(open(sys.argv[1]))
assert d["frames"] == 24 and len(d["servers"]) == 2, d
PY
same_as_one_daemon "${ports[1]}" "$work/shot_single" "$work/shot_farm" 24 "${shot[@]}"
cmp -s "$work/shot_single/frame_00000.png" "$work/shot_single/frame_00006.png" &&
  fail "the cylinder did not move between frames 0 and 6"
echo "farm: an animation's 24 frames over 2 daemons, identical to one daemon's"
