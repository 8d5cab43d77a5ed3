#!/usr/bin/env bash
# The README's commands, run as a user copies them: every `$T ...` (the tessera CLI) and
# `./build/default/clients/cli/tessera-render ...` line of its code blocks, in order, against a
# fresh tesserad, each of which must exit 0. Two substitutions only: the build directory and
# the assets directory are this build's, and the daemon's address comes from $TESSERA_SERVER.
# Skipped: lines with placeholders (ID, DIR, scene.glb, path.json, host1, dns:///, ...), and
# ./deploy/run.sh, cmake and the benchmark programs (the daemon stands in for run.sh; the
# benchmarks are smoke-run by their own tests).
# Usage: readme_test.sh README TESSERAD BUILD_DIR ASSETS_DIR
set -euo pipefail
readme=$1 tesserad=$2 build=$3 assets=$4
# shellcheck source=daemon.sh
source "$(dirname "$0")/daemon.sh"

python3 - "$readme" > "$work/commands" <<'PY'
import re, sys
text = open(sys.argv[1]).read()
skip = re.compile(r"\bID\b|\bDIR\b|scene\.glb|path\.json|host1|dns:///|\.\.\.|^\$ ")
for block in re.findall(r"```[a-z]*\n(.*?)```", text, re.S):
    lines, joined = [], ""
    for raw in block.splitlines():
        joined += raw.rstrip("\\").rstrip() + " " if raw.endswith("\\") else raw
        if raw.endswith("\\"):
            continue
        lines.append(joined.strip())
        joined = ""
    for line in lines:
        line = re.sub(r"\s+#\s.*$", "", line)  # trailing comments
        is_cli = line.startswith("$T ") or line.startswith("id=$($T ")
        is_render = line.startswith("./build/default/clients/cli/tessera-render ")
        if (is_cli or is_render) and "[options]" not in line and not skip.search(line):
            print(line)
PY
[[ $(wc -l < "$work/commands") -ge 10 ]] || fail "found only $(wc -l < "$work/commands") commands"

start_tesserad "$tesserad"

# Run from a scratch directory, so out/... lands there; the README's paths are relative to the
# checkout: ./build/default and ../shared/assets.
mkdir -p "$work/run" && cd "$work/run"
T=$build/clients/cli/tessera
n=0
while IFS= read -r line; do
  cmd=${line//.\/build\/default/$build}
  cmd=${cmd//..\/shared\/assets/$assets}
  n=$((n + 1))
  echo "[$n] $line"
  eval "$cmd" < /dev/null > "$work/out.txt" 2>&1 || fail "exit $? from: $line
$(tail -n 5 "$work/out.txt")"
done < "$work/commands"
echo "readme: $n commands ran"
