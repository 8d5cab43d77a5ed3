#!/usr/bin/env bash
# Checks the deployment files without Docker or a cluster:
#   - every YAML document under deploy/k8s parses and has apiVersion, kind and metadata.name;
#     selectors match pod labels, Services reach named ports, claims exist; kustomize builds
#   - the farm job's frame slicing (its sh script run with a stub tessera) covers every frame once;
#     ConfigMap .json data parses
#   - deploy/systemd/tesserad.flags is valid absl flagfile syntax and, with a real tesserad,
#     names only flags that binary knows
#   - systemd-analyze verify on deploy/systemd/tesserad.service (ExecStart pointed at the binary)
#   - deploy/Dockerfile: FROM lines, COPY sources exist and are not .dockerignored, the runtime
#     packages exist in Debian 12 and cover every shared library the built binaries link
# usage: deploy/validate.sh [TESSERAD]
#   TESSERAD: the tesserad binary (default build/default/server/tesserad; /bin/true works when
#   nothing is built: the checks that need the real binary are skipped). The tessera CLI is
#   looked for next to it in build/default/clients/cli/tessera.
# One line per check; exits non-zero at the first failure.
set -euo pipefail
cd "$(dirname "$0")/.."

ok() { echo "ok    $*"; }
skip() { echo "skip  $*"; }
info() { echo "info  $*"; }
fail() {
  echo "FAIL  $*"
  exit 1
}

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

bin=${1:-build/default/server/tesserad}
if [[ ! -x $bin ]]; then
  fail "binary: $bin is not an executable file (pass one, e.g. deploy/validate.sh /bin/true)"
fi
bin=$(readlink -f "$bin")
real_tesserad=0
# absl's --helpfull lists every flag as "    --name (help...)" and exits 1.
help=$(timeout 20 "$bin" --helpfull 2>&1 </dev/null || true)
if grep -q -- '^    --listen (' <<<"$help"; then real_tesserad=1; fi
if ((real_tesserad)); then info "binary: $bin (a tesserad)"; else info "binary: $bin (not a tesserad: binary checks skipped)"; fi

# --- Kubernetes manifests ------------------------------------------------------------------
command -v python3 >/dev/null || fail "k8s: python3 is missing"
python3 -c 'import yaml' 2>/dev/null || fail "k8s: the python3 yaml module is missing (apt-get install python3-yaml)"

python3 - deploy/k8s <<'PY' || exit 1
import glob, os, sys
import yaml

root = sys.argv[1]
files = sorted(glob.glob(os.path.join(root, "*.yaml")) + glob.glob(os.path.join(root, "*.yml")))
if not files:
    print(f"FAIL  k8s: no YAML files under {root}"); sys.exit(1)

docs = []  # (file, doc)
for path in files:
    try:
        with open(path) as f:
            loaded = [d for d in yaml.safe_load_all(f) if d is not None]
    except yaml.YAMLError as e:
        print(f"FAIL  yaml {path}: {e}"); sys.exit(1)
    if not loaded:
        print(f"FAIL  yaml {path}: no documents"); sys.exit(1)
    names = []
    for i, d in enumerate(loaded):
        where = f"{path} document {i + 1}"
        if not isinstance(d, dict):
            print(f"FAIL  yaml {where}: not a mapping"); sys.exit(1)
        for key in ("apiVersion", "kind"):
            if not isinstance(d.get(key), str) or not d[key]:
                print(f"FAIL  yaml {where}: no {key}"); sys.exit(1)
        meta = d.get("metadata")
        if not isinstance(meta, dict) or not isinstance(meta.get("name"), str) or not meta["name"]:
            print(f"FAIL  yaml {where} ({d['kind']}): no metadata.name"); sys.exit(1)
        names.append(f"{d['kind']}/{meta['name']}")
        docs.append((path, d))
    print(f"ok    yaml {path}: {len(loaded)} document(s): {', '.join(names)}")

def fail(msg):
    print(f"FAIL  k8s {msg}"); sys.exit(1)

def pod_template(d):
    if d["kind"] in ("Deployment", "StatefulSet", "DaemonSet", "Job", "ReplicaSet"):
        return d.get("spec", {}).get("template")
    return None

workloads = [(p, d) for p, d in docs if pod_template(d)]
claims = {d["metadata"]["name"] for _, d in docs if d["kind"] == "PersistentVolumeClaim"}
configmaps = {d["metadata"]["name"]: d for _, d in docs if d["kind"] == "ConfigMap"}
import json
for name, cm in configmaps.items():
    for key, value in (cm.get("data") or {}).items():
        if key.endswith(".json"):
            try:
                json.loads(value)
            except ValueError as e:
                print(f"FAIL  k8s ConfigMap/{name}: {key} is not JSON: {e}"); sys.exit(1)
            print(f"ok    k8s ConfigMap/{name}: {key} parses as JSON")

for path, d in workloads:
    name = f"{d['kind']}/{d['metadata']['name']}"
    tpl = pod_template(d)
    labels = tpl.get("metadata", {}).get("labels", {}) or {}
    sel = d["spec"].get("selector", {}).get("matchLabels")
    if d["kind"] != "Job":
        if not sel:
            fail(f"{name}: no spec.selector.matchLabels")
        if any(labels.get(k) != v for k, v in sel.items()):
            fail(f"{name}: selector {sel} does not match the pod labels {labels}")
    pod = tpl.get("spec", {})
    containers = pod.get("containers") or []
    if not containers:
        fail(f"{name}: no containers")
    volumes = {v["name"]: v for v in pod.get("volumes", []) or []}
    for c in containers:
        if not c.get("image"):
            fail(f"{name}: container {c.get('name')} has no image")
        for m in c.get("volumeMounts", []) or []:
            if m["name"] not in volumes:
                fail(f"{name}: volumeMount {m['name']} has no volume")
        ports = {p.get("name"): p["containerPort"] for p in c.get("ports", []) or []}
        # tesserad with TLS (the commented flags turned on): gRPC probes cannot speak TLS, so
        # they must ask the plaintext --health_listen port, never the service port.
        args = c.get("args", []) or []
        health = [a.split("=", 1)[1] for a in args if a.startswith("--health_listen=")]
        if "tesserad" in (c.get("name") or ""):
            if not health:
                fail(f"{name}: tesserad without --health_listen: its gRPC probes would fail once "
                     "TLS is on")
            hport = int(health[0].rsplit(":", 1)[1])
            if hport not in ports.values():
                fail(f"{name}: --health_listen port {hport} is not a container port")
            for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
                g = (c.get(probe) or {}).get("grpc")
                if g is None:
                    fail(f"{name}: no gRPC {probe}")
                port = ports.get(g["port"], g["port"])
                if port != hport:
                    fail(f"{name}: {probe} asks port {g['port']}, not the plaintext health port "
                         f"{hport}: it fails once --tls_cert is on")
            print(f"ok    k8s {name}: probes ask the plaintext health port {hport} (TLS-safe)")
        for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
            pr = c.get(probe)
            if not pr:
                continue
            for kind in ("grpc", "httpGet", "tcpSocket"):
                if kind in pr:
                    port = pr[kind].get("port")
                    if port not in ports and port not in ports.values():
                        fail(f"{name}: {probe} {kind} port {port} is not a container port")
    for v in volumes.values():
        pvc = v.get("persistentVolumeClaim")
        if pvc and pvc["claimName"] not in claims:
            fail(f"{name}: volume {v['name']} claims {pvc['claimName']}, which no file defines")
        cmv = v.get("configMap")
        if cmv and cmv["name"] not in configmaps and not cmv.get("optional"):
            fail(f"{name}: volume {v['name']} uses ConfigMap {cmv['name']}, which no file defines")
    print(f"ok    k8s {name}: selector, volumes, probe ports")

for path, d in docs:
    if d["kind"] != "Service":
        continue
    name = f"Service/{d['metadata']['name']}"
    sel = d["spec"].get("selector") or {}
    targets = []
    for _, w in workloads:
        labels = pod_template(w).get("metadata", {}).get("labels", {}) or {}
        if sel and all(labels.get(k) == v for k, v in sel.items()):
            targets.append(w)
    if not targets:
        fail(f"{name}: selector {sel} selects no workload's pods")
    for port in d["spec"].get("ports", []):
        tp = port.get("targetPort", port["port"])
        for w in targets:
            cports = [p for c in pod_template(w)["spec"]["containers"] for p in c.get("ports", []) or []]
            if not any(tp == p.get("name") or tp == p["containerPort"] for p in cports):
                fail(f"{name}: targetPort {tp} is not a port of {w['kind']}/{w['metadata']['name']}")
    print(f"ok    k8s {name}: selects {', '.join(w['kind'] + '/' + w['metadata']['name'] for w in targets)}; target ports exist")

kfile = os.path.join(root, "kustomization.yaml")
if os.path.exists(kfile):
    with open(kfile) as f:
        k = yaml.safe_load(f)
    listed = k.get("resources", [])
    for r in listed:
        if not os.path.exists(os.path.join(root, r)):
            fail(f"kustomization.yaml: resource {r} does not exist")
    others = {os.path.basename(p) for p in files} - {"kustomization.yaml"} - set(listed)
    if others:
        fail(f"kustomization.yaml does not list {sorted(others)}")
    print(f"ok    k8s kustomization.yaml lists every manifest: {', '.join(listed)}")
PY

if command -v kubectl >/dev/null; then
  if out=$(timeout 120 kubectl kustomize deploy/k8s 2>&1); then
    ok "kubectl kustomize deploy/k8s: builds ($(grep -c '^kind:' <<<"$out") objects)"
  else
    echo "$out"
    fail "kubectl kustomize deploy/k8s"
  fi
else
  skip "kubectl kustomize: kubectl is not installed"
fi

# The farm job's script, run for every index with a stub tessera that prints its arguments,
# in the job's environment (Kubernetes' $(VAR) references expanded, namespace "default").
python3 - deploy/k8s/farm-job.yaml "$tmp/farm" <<'PY' || exit 1
import os, re, sys, yaml
path, out = sys.argv[1], sys.argv[2]
docs = [d for d in yaml.safe_load_all(open(path)) if d]
job = next(d for d in docs if d["kind"] == "Job")
pod = job["spec"]["template"]["spec"]
c = pod["containers"][0]
os.makedirs(out, exist_ok=True)
open(os.path.join(out, "script.sh"), "w").write(c["args"][0])
env = {}
for e in c.get("env", []):
    if "value" in e:
        env[e["name"]] = re.sub(r"\$\((\w+)\)", lambda m: env.get(m.group(1), m.group(0)), e["value"])
    elif e.get("valueFrom", {}).get("fieldRef", {}).get("fieldPath") == "metadata.namespace":
        env[e["name"]] = "default"
for k, v in env.items():
    if "$(" in v or "\n" in v:
        print(f"FAIL  farm-job: env {k}={v!r} does not expand to one line"); sys.exit(1)
with open(os.path.join(out, "env"), "w") as f:
    for k, v in env.items():
        f.write(f"{k}={v}\n")
with open(os.path.join(out, "meta"), "w") as f:
    f.write(f"INDEXES={job['spec']['completions']}\n")
    for k in ("FIRST_FRAME", "LAST_FRAME", "COMPLETIONS"):
        f.write(f"{k}={env[k]}\n")
# KEYFRAMES must be a key of a ConfigMap mounted in the pod.
kf = env.get("KEYFRAMES", "")
if kf:
    vols = {v["name"]: v for v in pod.get("volumes", [])}
    ok = False
    for m in c.get("volumeMounts", []):
        v = vols.get(m["name"], {})
        if "configMap" in v and os.path.dirname(kf) == m["mountPath"].rstrip("/"):
            cm = next((d for d in docs if d["kind"] == "ConfigMap" and d["metadata"]["name"] == v["configMap"]["name"]), None)
            ok = cm is not None and os.path.basename(kf) in (cm.get("data") or {})
    if not ok:
        print(f"FAIL  farm-job: KEYFRAMES={kf} is not a key of a ConfigMap mounted there"); sys.exit(1)
PY
mkdir -p "$tmp/farm/bin"
printf '#!/bin/sh\necho "tessera $*"\n' >"$tmp/farm/bin/tessera"
chmod +x "$tmp/farm/bin/tessera"
(
  # shellcheck disable=SC1091
  . "$tmp/farm/meta"
  [[ $COMPLETIONS == "$INDEXES" ]] || fail "farm-job: env COMPLETIONS=$COMPLETIONS but spec.completions=$INDEXES"
  mapfile -t jobenv <"$tmp/farm/env"
  covered=()
  slices=()
  for ((i = 0; i < INDEXES; i++)); do
    line=$(env -i PATH="$tmp/farm/bin:/usr/bin:/bin" JOB_COMPLETION_INDEX=$i "${jobenv[@]}" \
      sh "$tmp/farm/script.sh") || fail "farm-job: the script for index $i failed: $line"
    if grep -q 'no frames left' <<<"$line"; then
      slices+=("$i:none")
      continue
    fi
    line=$(grep '^tessera ' <<<"$line") || fail "farm-job: the script for index $i ran no tessera"
    [[ $line == "tessera job submit --servers dns:///"* ]] || fail "farm-job: index $i: not a job submit --servers dns:///...: $line"
    [[ $line =~ --frames\ ([0-9]+)\.\.([0-9]+) ]] || fail "farm-job: index $i: no --frames A..B in: $line"
    for ((f = BASH_REMATCH[1]; f <= BASH_REMATCH[2]; f++)); do covered+=("$f"); done
    slices+=("$i:${BASH_REMATCH[1]}..${BASH_REMATCH[2]}")
  done
  want=$(seq "$FIRST_FRAME" "$LAST_FRAME" | tr '\n' ' ')
  got=$(printf '%s\n' "${covered[@]}" | sort -n | tr '\n' ' ')
  [[ $want == "$got" ]] || fail "farm-job: the slices ${slices[*]} do not cover $FIRST_FRAME..$LAST_FRAME exactly once"
  ok "farm-job: indexes ${slices[*]} cover frames $FIRST_FRAME..$LAST_FRAME exactly once"
  info "farm-job: index 0 runs: $(env -i PATH="$tmp/farm/bin:/usr/bin:/bin" JOB_COMPLETION_INDEX=0 "${jobenv[@]}" sh "$tmp/farm/script.sh" | grep '^tessera ')"
)

# --- tesserad flagfile ---------------------------------------------------------------------
flags=deploy/systemd/tesserad.flags
[[ -f $flags ]] || fail "flagfile: $flags is missing"
n=0
names=()
while IFS= read -r line || [[ -n $line ]]; do
  n=$((n + 1))
  stripped=${line#"${line%%[![:space:]]*}"}
  [[ -z $stripped || $stripped == \#* ]] && continue
  # absl takes everything after '=' as the value: no trailing blanks, no end-of-line comments.
  [[ $stripped =~ ^--([a-z0-9_]+)(=.*)?$ ]] || fail "flagfile: $flags:$n: not --flag=value: $line"
  names+=("${BASH_REMATCH[1]}")
  if [[ $line =~ [[:space:]]$ ]]; then
    fail "flagfile: $flags:$n: trailing whitespace (it would be part of the value)"
  fi
  if [[ $line == *[[:space:]]#* ]]; then
    fail "flagfile: $flags:$n: an end-of-line comment (it would be part of the value)"
  fi
done <"$flags"
ok "flagfile: $flags: ${#names[@]} flags, absl flagfile syntax"
if ((real_tesserad)); then
  known=$(sed -n 's/^    --\([a-z0-9_]*\) (.*/\1/p' <<<"$help")
  for f in "${names[@]}"; do
    grep -qx -- "$f" <<<"$known" || fail "flagfile: $bin does not know --$f (an older build? rebuild tesserad)"
  done
  ok "flagfile: every flag is known to $bin"
else
  skip "flagfile: flag names not checked against a tesserad binary"
fi

# --- systemd unit --------------------------------------------------------------------------
unit=deploy/systemd/tesserad.service
[[ -f $unit ]] || fail "systemd: $unit is missing"
if command -v systemd-analyze >/dev/null; then
  mkdir -p "$tmp/unit"
  sed "s#^ExecStart=/usr/local/bin/tesserad #ExecStart=$bin #" "$unit" >"$tmp/unit/tesserad.service"
  grep -q "^ExecStart=$bin " "$tmp/unit/tesserad.service" || fail "systemd: no ExecStart=/usr/local/bin/tesserad line to rewrite"
  # In a container verify also complains about the host's units; only lines naming ours count.
  out=$(systemd-analyze verify --man=no "$tmp/unit/tesserad.service" 2>&1 || true)
  bad=$(grep -F 'tesserad.service' <<<"$out" || true)
  if [[ -n $bad ]]; then
    echo "$bad"
    fail "systemd: systemd-analyze verify $unit (ExecStart=$bin)"
  fi
  ok "systemd: systemd-analyze verify $unit (ExecStart=$bin): no findings"
  if score=$(systemd-analyze security --offline=true --no-pager "$tmp/unit/tesserad.service" 2>/dev/null |
    grep -F 'Overall exposure level'); then
    info "systemd: ${score#→ }"
  fi
else
  skip "systemd: systemd-analyze is not installed (apt-get install systemd); unit not verified"
fi

# --- Dockerfile ----------------------------------------------------------------------------
df=deploy/Dockerfile
[[ -f $df ]] || fail "docker: $df is missing"
[[ -f .dockerignore ]] || fail "docker: .dockerignore is missing"
froms=$(grep -cE '^FROM[[:space:]]' "$df" || true)
((froms >= 2)) || fail "docker: $df has $froms FROM lines (want a build and a runtime stage)"
grep -qE '^FROM[[:space:]].*[[:space:]]AS[[:space:]]+build$' "$df" || fail "docker: no 'FROM ... AS build' stage"
for a in DEBIAN_IMAGE DEBIAN_SLIM_IMAGE; do
  grep -qE "^ARG $a=debian:12" "$df" || fail "docker: ARG $a is not a debian:12 image"
done
ok "docker: $froms FROM lines (build + runtime on Debian 12)"
for k in ENTRYPOINT EXPOSE HEALTHCHECK USER VOLUME; do
  grep -qE "^${k}[[:space:]]" "$df" || fail "docker: no $k instruction"
done
ok "docker: ENTRYPOINT, EXPOSE, HEALTHCHECK, USER, VOLUME present"

python3 - "$df" .dockerignore <<'PY' || exit 1
import fnmatch, os, shlex, sys
df, ignore = sys.argv[1], sys.argv[2]
patterns = []
for line in open(ignore):
    line = line.strip()
    if line and not line.startswith("#"):
        patterns.append(os.path.normpath(line.rstrip("/")))

def ignored(path):
    path = os.path.normpath(path)
    parts = path.split("/")
    for i in range(1, len(parts) + 1):
        prefix = "/".join(parts[:i])
        for p in patterns:
            if p.startswith("!"):
                continue
            if fnmatch.fnmatch(prefix, p) or (p.startswith("**/") and fnmatch.fnmatch(parts[i - 1], p[3:])):
                return p
    return None

# Join continuation lines, then look at COPY/ADD instructions.
text = open(df).read().replace("\\\n", " ")
n = 0
for line in text.splitlines():
    words = line.strip().split(None, 1)
    if not words or words[0].upper() not in ("COPY", "ADD"):
        continue
    args = shlex.split(words[1])
    opts = [a for a in args if a.startswith("--")]
    paths = [a for a in args if not a.startswith("--")]
    if any(o.startswith("--from=") for o in opts):
        continue  # from another stage
    for src in paths[:-1]:
        if src in (".", "./"):
            continue
        if not os.path.exists(src):
            print(f"FAIL  docker: COPY source {src} does not exist in the repository"); sys.exit(1)
        pat = ignored(src)
        if pat:
            print(f"FAIL  docker: COPY source {src} is excluded by .dockerignore ({pat})"); sys.exit(1)
        n += 1
print(f"ok    docker: {n} COPY source(s) from the context exist and are not .dockerignored")
PY

# The runtime stage's packages: all of them must exist in Debian 12 (this machine's lists).
pkgs=$(python3 - "$df" <<'PY'
import re, sys
text = open(sys.argv[1]).read().replace("\\\n", " ")
stages = re.split(r"(?m)^FROM\s", text)
runtime = stages[-1]
m = re.search(r"apt-get install\s+(.*?)(&&|$)", runtime, re.S | re.M)
print(" ".join(w for w in m.group(1).split() if not w.startswith("-")) if m else "")
PY
)
[[ -n $pkgs ]] || fail "docker: no apt-get install in the runtime stage"
# Package lists present (a machine whose lists were cleaned cannot say; skipped then).
if command -v apt-cache >/dev/null && [[ -r /etc/debian_version && $(cut -d. -f1 /etc/debian_version) == 12 ]] &&
  apt-cache show --no-all-versions libc6 >/dev/null 2>&1; then
  # shellcheck disable=SC2086
  # (One call for all; it says nothing about missing ones when others are found, so count.)
  found=$(apt-cache show --no-all-versions $pkgs 2>/dev/null | grep -c '^Package:' || true)
  if ((found != $(wc -w <<<"$pkgs"))); then
    for p in $pkgs; do
      apt-cache show --no-all-versions "$p" >/dev/null 2>&1 || fail "docker: runtime package $p is not in this machine's Debian 12 lists"
    done
  fi
  ok "docker: the $(wc -w <<<"$pkgs") runtime packages exist in Debian 12"
  cli=build/default/clients/cli/tessera
  if ((real_tesserad)) && [[ -x $cli ]] && command -v ldd >/dev/null; then
    # Packages the runtime packages bring with them, plus what debian:12-slim already has.
    # shellcheck disable=SC2086
    # (With --recurse every package of the closure is listed unindented.)
    closure=$(apt-cache depends --recurse --no-recommends --no-suggests --no-conflicts \
      --no-breaks --no-replaces --no-enhances $pkgs 2>/dev/null | grep -E '^[a-z0-9]' | sort -u)
    closure+=$'\n'"libc6"$'\n'"libgcc-s1"$'\n'"libstdc++6"$'\n'"zlib1g"
    libs=$(ldd "$bin" "$cli" | awk '$3 ~ /^\// {print $3}' | sort -u)
    # dpkg knows a library under /lib or /usr/lib (merged /usr): ask for both spellings.
    cands=$(for l in $libs; do echo "$l"; case $l in /usr/*) echo "${l#/usr}" ;; *) echo "/usr$l" ;; esac; done)
    # shellcheck disable=SC2086
    owners=$(dpkg -S $cands 2>/dev/null | grep -v '^diversion' || true)
    for lib in $libs; do
      owner=$(awk -v a="${lib#/usr}" -v b="/usr${lib#/usr}" \
        '$NF == a || $NF == b { split($1, x, ":"); print x[1]; exit }' <<<"$owners")
      [[ -n $owner ]] || fail "docker: $lib (linked by the binaries) belongs to no package"
      grep -qx -- "$owner" <<<"$closure" || fail "docker: $lib is in $owner, which the runtime stage does not install"
    done
    ok "docker: every shared library of $bin and $cli ($(wc -w <<<"$libs")) comes with the runtime packages"
  else
    skip "docker: shared libraries not checked (needs a built tesserad and $cli)"
  fi
else
  skip "docker: runtime packages not checked (needs apt-cache with Debian 12 lists)"
fi

echo "all checks passed (not run here: docker build, a Kubernetes cluster; see deploy/README.md)"
