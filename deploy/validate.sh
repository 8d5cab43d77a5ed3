#!/usr/bin/env bash
# Checks the deployment files without Docker or a cluster:
#   - every YAML document under deploy/k8s parses and has apiVersion, kind and metadata.name;
#     selectors match pod labels, Services reach named ports, claims exist; kustomize builds;
#     live viewing across replicas: the shared scene store's claim and mount, readiness on
#     tessera.v1.RenderService, the PodDisruptionBudget, the HPA and its adapter rule, the
#     gateway's dns:/// name of the headless Service (deploy/k8s_check.py lists them); with a
#     real tesserad, every flag the manifests pass it is one it knows
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
# Debian's python3 is where install-deps.sh puts yaml and jsonpatch; another python3 first on
# PATH (pyenv, a virtualenv) is used only if it has both.
py=""
for cand in /usr/bin/python3 python3; do
  if command -v "$cand" >/dev/null && "$cand" -c 'import yaml, jsonpatch' 2>/dev/null; then
    py=$cand
    break
  fi
done
[[ -n $py ]] || fail "k8s: no python3 with the yaml and jsonpatch modules (apt-get install python3-yaml python3-jsonpatch)"
# The comparison needs kustomize >= 4 (components, labels); kubectl 1.14-1.20 (Debian 12's
# kubernetes-client) embeds 2.0 and does not report kustomizeVersion.
kubectl=$(command -v kubectl || true)
kversion=""
if [[ -n $kubectl ]]; then
  kversion=$(timeout 20 "$kubectl" version --client -o json 2>/dev/null |
    "$py" -c 'import json, sys; print(json.load(sys.stdin).get("kustomizeVersion", ""))' 2>/dev/null || true)
fi
if [[ -z $kubectl ]]; then
  skip "k8s: kubectl is not installed: builds not compared with kubectl kustomize"
elif [[ ! $kversion =~ ^v([0-9]+) ]] || ((BASH_REMATCH[1] < 4)); then
  skip "k8s: $kubectl has kustomize '${kversion:-2.x}', older than 4: builds not compared"
  kubectl=""
fi
# With a real tesserad, every flag the manifests pass it must be one it knows.
known_flags=()
if ((real_tesserad)); then
  sed -n 's/^    --\([a-z0-9_]*\) (.*/\1/p' <<<"$help" >"$tmp/tesserad-flags"
  known_flags=(--tesserad-flags "$tmp/tesserad-flags")
else
  skip "k8s: tesserad's arguments in the manifests not checked against a tesserad binary"
fi
"$py" deploy/k8s_check.py deploy/k8s ${kubectl:+"$kubectl"} "${known_flags[@]}" || exit 1
((real_tesserad)) && ok "k8s: every tesserad argument in every build is a flag $bin knows"

# Planted faults: each copy of deploy/k8s with one mistake must fail with the expected message
# (so the checks above can fail).
planted() { # description, expected message, sed script, file under deploy/k8s
  rm -rf "$tmp/k8s" && cp -r deploy/k8s "$tmp/k8s"
  sed -i "$3" "$tmp/k8s/$4"
  cmp -s "deploy/k8s/$4" "$tmp/k8s/$4" && fail "planted fault '$1': the sed script changed nothing"
  local out
  if out=$("$py" deploy/k8s_check.py "$tmp/k8s" "${known_flags[@]}" 2>&1); then
    fail "planted fault '$1': the checks passed"
  fi
  grep -qF -- "$2" <<<"$out" || fail "planted fault '$1': failed, but not with '$2': $(tail -1 <<<"$out")"
  ok "k8s planted fault caught: $1"
}
planted "gateway without TLS while tesserad has it" "speaks TLS but the gateway does not" \
  's#value: --tls-ca=/etc/tessera/ca/ca.crt#value: --max-upload-mb=64#' components/tls/kustomization.yaml
planted "readiness probe on the TLS port" "not the plaintext health port" \
  '/readinessProbe:/,/port:/s/port: 50052/port: 50051/' base/tesserad.yaml
planted "base flags reordered under the local overlay" "patch on Deployment/tesserad" \
  's/- --encoder_threads=4/- --encoder_threads=3/' base/tesserad.yaml
planted "TLS key outside every mount" "is in no volume mount" \
  's#--tls_key=/etc/tessera/tls/tls.key#--tls_key=/etc/tls.key#' components/tls/kustomization.yaml
planted "gateway's CA not projected from the Secret" "projects only" \
  's#items: \[{key: ca.crt, path: ca.crt}\]#items: [{key: ca.crt, path: root.crt}]#' components/tls/kustomization.yaml
planted "a manifest no kustomization uses" "used by no kustomization" \
  '/^  - farm-job.yaml$/d' examples/farm-job/kustomization.yaml
planted "a Service targeting a missing port" "is not a port of" \
  's/targetPort: metrics/targetPort: prometheus/' base/tesserad.yaml
# Live viewing across replicas.
planted "readiness on the liveness service" "not tessera.v1.RenderService" \
  's/service: tessera.v1.RenderService/service: ""/' base/tesserad.yaml
planted "liveness on the readiness service" "a full replica would be restarted" \
  '/livenessProbe:/,/service:/s/service: ""/service: tessera.v1.RenderService/' base/tesserad.yaml
planted "scene store outside every mount" "replicas would not share it" \
  's#--scene_store_dir=/srv/tessera/scenes/store#--scene_store_dir=/var/cache/scenes#' base/tesserad.yaml
planted "scene store on a ReadWriteOnce claim" "not ReadWriteMany" \
  's/accessModes: \["ReadWriteMany"\]/accessModes: ["ReadWriteOnce"]/' base/tesserad.yaml
planted "scene store cap as large as its claim" "leaves less than 10%" \
  's/--scene_store_max_mb=16384/--scene_store_max_mb=20480/' base/tesserad.yaml
planted "grace period shorter than the drain" "does not cover" \
  's/terminationGracePeriodSeconds: 30/terminationGracePeriodSeconds: 5/' base/tesserad.yaml
planted "PodDisruptionBudget selecting other pods" "no PodDisruptionBudget selects the tesserad pods" \
  '/^kind: PodDisruptionBudget/,/^---/s#app.kubernetes.io/name: tesserad$#app.kubernetes.io/name: tessera-render#' base/tesserad.yaml
planted "unready replicas published to the gateway" "publishNotReadyAddresses is true" \
  's/publishNotReadyAddresses: false/publishNotReadyAddresses: true/' base/tesserad.yaml
planted "gateway on the ClusterIP Service" "is not a headless Service in this build" \
  's#dns:///tesserad-headless\.#dns:///tesserad.#' base/web-gateway.yaml
planted "gateway on a port the headless Service lacks" "is not a port of" \
  's#svc.cluster.local:50051#svc.cluster.local:50052#' base/web-gateway.yaml
planted "gateway's \$(VAR) without its env variable" "is not one of its env variables" \
  's/- name: POD_NAMESPACE/- name: NAMESPACE/' base/web-gateway.yaml
planted "HPA on a Deployment not in the build" "is not in this build" \
  '/scaleTargetRef:/,/name:/s/name: tesserad/name: tessera-render/' examples/autoscale/hpa.yaml
planted "HPA while the Deployment sets replicas" "sets spec.replicas" \
  '/- op: remove/,/path: \/spec\/replicas/d' examples/autoscale/kustomization.yaml
planted "HPA aiming at --max_sessions" "is not below --max_sessions" \
  's/averageValue: "6"/averageValue: "8"/' examples/autoscale/hpa.yaml
planted "HPA metric no adapter rule serves" "served by no Prometheus adapter rule" \
  's/as: "tessera_sessions"/as: "tessera_open_sessions"/' examples/autoscale/prometheus-adapter-rule.yaml
if ((real_tesserad)); then
  planted "a tesserad flag the binary does not know" "does not know --max_session " \
    's/- --max_sessions=8/- --max_session=8/' base/tesserad.yaml
fi

# The farm job's script, run for every index with a stub tessera that prints its arguments,
# in the job's environment (Kubernetes' $(VAR) references expanded, namespace "default").
"$py" - deploy/k8s/examples/farm-job/farm-job.yaml "$tmp/farm" <<'PY' || exit 1
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

"$py" - "$df" .dockerignore <<'PY' || exit 1
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
pkgs=$("$py" - "$df" <<'PY'
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
