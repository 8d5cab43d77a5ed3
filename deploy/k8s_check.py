#!/usr/bin/env python3
"""Builds every kustomization under deploy/k8s and checks what each would apply.

Run by deploy/validate.sh; usage: k8s_check.py ROOT [KUBECTL] [--tesserad-flags FILE]

A fresh machine has no kustomize (Debian 12's kubernetes-client is 1.20, whose kustomize 2.0
predates components, labels and replicas), so this builds the subset of kustomize the files use:
resources (files and directories), components, images, replicas, labels (metadata only) and
patches made of JSON 6902 operations (python3-jsonpatch applies them; their "test" operations
guard against a base that changed under them). Any other kustomization field is refused rather
than ignored. With KUBECTL (a kubectl with kustomize), each build is also compared with
`kubectl kustomize`, the reference.

Checks, for every target (a Kustomization directory; Components are checked through the
targets that use them):
  - every document has apiVersion, kind and metadata.name; names are unique per kind;
  - selectors match pod labels, volume mounts have volumes, probe ports are container ports,
    claims and ConfigMaps exist, Services select a workload whose ports they target;
  - tesserad's probes ask its plaintext --health_listen port (the gRPC probes cannot speak TLS);
  - every file a flag names (--tls_cert, --tls_key, --token_file, --tls-ca, ...) lies in a
    volume mount of that container, and a Secret volume with items projects that file;
  - TLS and tokens agree between tesserad and the web gateway: TLS on tesserad means the gateway
    talks TLS (and the reverse), tokens on tesserad mean the gateway sends one;
  - ConfigMap data named *.json parses (and *.yaml);
  - live viewing across replicas: a tesserad with more than one replica (or an HPA) keeps
    --scene_store_dir on a writable mount of a ReadWriteMany claim in the build (one replica:
    any claim or an emptyDir), with --scene_store_max_mb at most 90% of the volume; its
    readiness probe asks tessera.v1.RenderService (load), startup and liveness "";
    terminationGracePeriodSeconds covers --shutdown_grace_ms + 5 s; a PodDisruptionBudget
    selects its pods and lets a drain proceed (maxUnavailable >= 1, or minAvailable below the
    replicas); an HPA targets a workload of the build that sets no spec.replicas, aims below
    --max_sessions, and asks a metric that a Prometheus adapter rule in a ConfigMap of the
    build serves; the web gateway's --server (or TESSERA_SERVER), $(VAR)s expanded, is
    dns:///<headless Service>[.<namespace>[.svc[.cluster.local]]]:<port> of a Service in the
    build that selects the tesserad pods, leads that port to tesserad's grpc port and does not
    publish unready addresses;
  - with --tesserad-flags FILE (the flag names a built tesserad knows), every tesserad argument
    is a known flag.
And for the tree: every YAML file under ROOT is used by some kustomization (nothing stale).
"""
import copy
import glob
import json
import os
import re
import subprocess
import sys

import jsonpatch
import yaml


class Failure(Exception):
    pass


def fail(msg):
    raise Failure(msg)


def load_docs(path):
    try:
        with open(path) as f:
            docs = [d for d in yaml.safe_load_all(f) if d is not None]
    except yaml.YAMLError as e:
        fail(f"yaml {path}: {e}")
    if not docs:
        fail(f"yaml {path}: no documents")
    for i, d in enumerate(docs):
        where = f"{path} document {i + 1}"
        if not isinstance(d, dict):
            fail(f"yaml {where}: not a mapping")
        for key in ("apiVersion", "kind"):
            if not isinstance(d.get(key), str) or not d[key]:
                fail(f"yaml {where}: no {key}")
        meta = d.get("metadata")
        if not isinstance(meta, dict) or not isinstance(meta.get("name"), str) or not meta["name"]:
            fail(f"yaml {where} ({d['kind']}): no metadata.name")
    return docs


# --- building ----------------------------------------------------------------------------------

KUSTOMIZATION_FIELDS = {"apiVersion", "kind", "metadata", "resources", "components", "images",
                        "replicas", "labels", "patches"}


def read_kustomization(directory):
    path = os.path.join(directory, "kustomization.yaml")
    if not os.path.exists(path):
        fail(f"{directory}: no kustomization.yaml")
    with open(path) as f:
        k = yaml.safe_load(f) or {}
    unknown = set(k) - KUSTOMIZATION_FIELDS
    if unknown:
        fail(f"{path}: {sorted(unknown)} not supported by deploy/k8s_check.py (extend it, and "
             "compare with kubectl kustomize)")
    return path, k


def select(docs, target):
    for key in target:
        if key not in ("kind", "name"):
            fail(f"patch target field {key} not supported")
    return [d for d in docs
            if d["kind"] == target.get("kind", d["kind"])
            and d["metadata"]["name"] == target.get("name", d["metadata"]["name"])]


def apply_transformers(kpath, k, docs, used):
    directory = os.path.dirname(kpath)
    for p in k.get("patches", []) or []:
        if "path" in p:
            ppath = os.path.normpath(os.path.join(directory, p["path"]))
            used.add(ppath)
            with open(ppath) as f:
                ops = yaml.safe_load(f)
        else:
            ops = yaml.safe_load(p["patch"])
        if not isinstance(ops, list):
            fail(f"{kpath}: only JSON 6902 patches (a list of operations) are supported")
        targets = select(docs, p.get("target") or fail(f"{kpath}: a patch without a target"))
        if not targets:
            fail(f"{kpath}: patch target {p['target']} matches nothing")
        for d in targets:
            try:
                patched = jsonpatch.apply_patch(d, ops)
            except (jsonpatch.JsonPatchException, jsonpatch.JsonPointerException) as e:
                fail(f"{kpath}: patch on {d['kind']}/{d['metadata']['name']}: {e}")
            d.clear()
            d.update(patched)
    for r in k.get("replicas", []) or []:
        hits = [d for d in docs if d["metadata"]["name"] == r["name"] and "replicas" in d.get("spec", {})]
        if not hits:
            fail(f"{kpath}: replicas for {r['name']}, which has no spec.replicas")
        for d in hits:
            d["spec"]["replicas"] = r["count"]
    for img in k.get("images", []) or []:
        for d in docs:
            for c in containers_of(d):
                # name[:tag]: the tag is after the last '/', so a registry port is no tag.
                image = c["image"]
                if "@" in image:
                    fail(f"{kpath}: image {image}: digests not supported by this check")
                slash = image.rfind("/")
                colon = image.rfind(":")
                name, tag = (image[:colon], image[colon + 1:]) if colon > slash else (image, "")
                if name == img["name"]:
                    new_tag = img.get("newTag", tag)
                    c["image"] = img.get("newName", name) + (f":{new_tag}" if new_tag else "")
    for lab in k.get("labels", []) or []:
        if set(lab) - {"pairs"}:
            fail(f"{kpath}: labels with {sorted(set(lab) - {'pairs'})} not supported")
        for d in docs:
            d["metadata"].setdefault("labels", {}).update(lab["pairs"])


def build(directory, used, component=False):
    """The documents `kubectl kustomize directory` would print (order aside)."""
    kpath, k = read_kustomization(directory)
    used.add(os.path.normpath(kpath))
    want = "Component" if component else "Kustomization"
    if k.get("kind", "Kustomization") != want:
        fail(f"{kpath}: kind {k.get('kind')}, used as a {want}")
    docs = []
    for r in k.get("resources", []) or []:
        path = os.path.normpath(os.path.join(directory, r))
        if os.path.isdir(path):
            docs += build(path, used)
        elif os.path.isfile(path):
            used.add(path)
            docs += copy.deepcopy(load_docs(path))
        else:
            fail(f"{kpath}: resource {r} does not exist")
    apply_components(kpath, k, docs, used)
    apply_transformers(kpath, k, docs, used)
    return docs


def apply_components(kpath, k, docs, used):
    for c in k.get("components", []) or []:
        path = os.path.normpath(os.path.join(os.path.dirname(kpath), c))
        ckpath, ck = read_kustomization(path)
        used.add(os.path.normpath(ckpath))
        if ck.get("kind") != "Component":
            fail(f"{kpath}: component {c} is a {ck.get('kind')}")
        for r in ck.get("resources", []) or []:
            rpath = os.path.normpath(os.path.join(path, r))
            used.add(rpath)
            docs += copy.deepcopy(load_docs(rpath))
        apply_components(ckpath, ck, docs, used)
        apply_transformers(ckpath, ck, docs, used)


# --- checks ------------------------------------------------------------------------------------

def pod_template(d):
    if d["kind"] in ("Deployment", "StatefulSet", "DaemonSet", "Job", "ReplicaSet"):
        return d.get("spec", {}).get("template")
    return None


def containers_of(d):
    tpl = pod_template(d)
    return (tpl.get("spec", {}).get("containers") or []) if tpl else []


def flag_values(args, *names):
    """{flag: value} of --flag=value arguments among `names`."""
    out = {}
    for a in args:
        flag, eq, value = a.partition("=")
        if eq and flag in names:
            out[flag] = value
    return out


def check_files(name, c, volumes, files):
    """Every path in `files` (flag -> path) lies under a mount of `c` that provides it."""
    for flag, path in files.items():
        mounts = [m for m in c.get("volumeMounts", []) or []
                  if path.startswith(m["mountPath"].rstrip("/") + "/")]
        if not mounts:
            fail(f"{name}: {flag}={path} is in no volume mount of container {c['name']}")
        m = max(mounts, key=lambda m: len(m["mountPath"]))
        v = volumes[m["name"]]
        rel = path[len(m["mountPath"].rstrip("/")) + 1:]
        for kind in ("secret", "configMap"):
            items = (v.get(kind) or {}).get("items")
            if items and rel not in [i["path"] for i in items]:
                fail(f"{name}: {flag}={path}: volume {m['name']} projects only "
                     f"{[i['path'] for i in items]}")


def check_target(label, docs):
    out = []
    seen = set()
    for d in docs:
        key = (d["kind"], d["metadata"]["name"])
        if key in seen:
            fail(f"{label}: two {key[0]}/{key[1]}")
        seen.add(key)
    workloads = [d for d in docs if pod_template(d)]
    claims = {d["metadata"]["name"] for d in docs if d["kind"] == "PersistentVolumeClaim"}
    configmaps = {d["metadata"]["name"]: d for d in docs if d["kind"] == "ConfigMap"}
    for name, cm in configmaps.items():
        for key, value in (cm.get("data") or {}).items():
            if key.endswith(".json"):
                try:
                    json.loads(value)
                except ValueError as e:
                    fail(f"{label} ConfigMap/{name}: {key} is not JSON: {e}")
            elif key.endswith((".yaml", ".yml")):
                try:
                    yaml.safe_load(value)
                except yaml.YAMLError as e:
                    fail(f"{label} ConfigMap/{name}: {key} is not YAML: {e}")

    tesserad = None  # (name, args, env names)
    gateway = None
    for d in workloads:
        name = f"{label} {d['kind']}/{d['metadata']['name']}"
        tpl = pod_template(d)
        labels = tpl.get("metadata", {}).get("labels", {}) or {}
        sel = d["spec"].get("selector", {}).get("matchLabels")
        if d["kind"] != "Job":
            if not sel:
                fail(f"{name}: no spec.selector.matchLabels")
            if any(labels.get(k) != v for k, v in sel.items()):
                fail(f"{name}: selector {sel} does not match the pod labels {labels}")
        pod = tpl.get("spec", {})
        if not containers_of(d):
            fail(f"{name}: no containers")
        volumes = {v["name"]: v for v in pod.get("volumes", []) or []}
        for v in volumes.values():
            pvc = v.get("persistentVolumeClaim")
            if pvc and pvc["claimName"] not in claims:
                fail(f"{name}: volume {v['name']} claims {pvc['claimName']}, which is not in this build")
            cmv = v.get("configMap")
            if cmv and cmv["name"] not in configmaps and not cmv.get("optional"):
                fail(f"{name}: volume {v['name']} uses ConfigMap {cmv['name']}, which is not in this build")
        for c in containers_of(d):
            if not c.get("image"):
                fail(f"{name}: container {c.get('name')} has no image")
            for m in c.get("volumeMounts", []) or []:
                if m["name"] not in volumes:
                    fail(f"{name}: volumeMount {m['name']} has no volume")
            ports = {p.get("name"): p["containerPort"] for p in c.get("ports", []) or []}
            args = c.get("args", []) or []
            env = {e["name"] for e in c.get("env", []) or []}
            for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
                pr = c.get(probe) or {}
                for kind in ("grpc", "httpGet", "tcpSocket"):
                    if kind in pr:
                        port = pr[kind].get("port")
                        if port not in ports and port not in ports.values():
                            fail(f"{name}: {probe} {kind} port {port} is not a container port")
            if c["name"] == "tesserad":
                # gRPC probes cannot speak TLS: they must ask the plaintext health port.
                health = flag_values(args, "--health_listen").get("--health_listen")
                if not health:
                    fail(f"{name}: tesserad without --health_listen: its gRPC probes would fail "
                         "once TLS is on")
                hport = int(health.rsplit(":", 1)[1])
                if hport not in ports.values():
                    fail(f"{name}: --health_listen port {hport} is not a container port")
                for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
                    g = (c.get(probe) or {}).get("grpc")
                    if g is None:
                        fail(f"{name}: no gRPC {probe}")
                    if ports.get(g["port"], g["port"]) != hport:
                        fail(f"{name}: {probe} asks port {g['port']}, not the plaintext health "
                             f"port {hport}: it fails once --tls_cert is on")
                files = flag_values(args, "--tls_cert", "--tls_key", "--tls_client_ca", "--token_file")
                if ("--tls_cert" in files) != ("--tls_key" in files):
                    fail(f"{name}: --tls_cert and --tls_key go together")
                check_files(name, c, volumes, files)
                tesserad = (name, files)
            elif c["name"] == "web":
                files = flag_values(args, "--tls-ca", "--token-file")
                check_files(name, c, volumes, files)
                tls = "--tls" in args or "--tls-ca" in files
                token = "--token-file" in files or "TESSERA_TOKEN" in env
                gateway = (name, tls, token)
        out.append(f"{name}: selector, volumes, probe ports, files named by flags")

    if tesserad and gateway:
        tname, tfiles = tesserad
        gname, gtls, gtoken = gateway
        if ("--tls_cert" in tfiles) != gtls:
            fail(f"{label}: tesserad {'speaks' if '--tls_cert' in tfiles else 'does not speak'} "
                 f"TLS but the gateway {'does' if gtls else 'does not'} ({gname})")
        if "--token_file" in tfiles and not gtoken:
            fail(f"{label}: tesserad wants tokens (--token_file) but the gateway sends none")
        out.append(f"{label}: tesserad and gateway agree: TLS {'on' if gtls else 'off'}, "
                   f"tokens {'on' if '--token_file' in tfiles else 'off'}; "
                   "probes on the plaintext health port")

    for d in docs:
        if d["kind"] != "Service":
            continue
        name = f"{label} Service/{d['metadata']['name']}"
        sel = d["spec"].get("selector") or {}
        targets = [w for w in workloads if sel and all(
            (pod_template(w).get("metadata", {}).get("labels", {}) or {}).get(k) == v
            for k, v in sel.items())]
        if not targets:
            fail(f"{name}: selector {sel} selects no workload's pods")
        for port in d["spec"].get("ports", []):
            tp = port.get("targetPort", port["port"])
            for w in targets:
                cports = [p for c in containers_of(w) for p in c.get("ports", []) or []]
                if not any(tp == p.get("name") or tp == p["containerPort"] for p in cports):
                    fail(f"{name}: targetPort {tp} is not a port of {w['kind']}/{w['metadata']['name']}")
        out.append(f"{name}: selects {', '.join(w['kind'] + '/' + w['metadata']['name'] for w in targets)}")
    out += check_replicas(label, docs, workloads)
    return out


# --- live viewing across replicas ----------------------------------------------------------------

READINESS_SERVICE = "tessera.v1.RenderService"
# tesserad's defaults for the flags the checks below read (tesserad --help).
TESSERAD_DEFAULTS = {"--max_sessions": "64", "--scene_store_max_mb": "20480",
                     "--shutdown_grace_ms": "3000"}
# Set by main from --tesserad-flags FILE: the flag names a built tesserad knows.
KNOWN_TESSERAD_FLAGS = None

QUANTITY = {"": 1, "m": 0.001, "k": 1000, "M": 1000**2, "G": 1000**3, "T": 1000**4,
            "Ki": 1024, "Mi": 1024**2, "Gi": 1024**3, "Ti": 1024**4}


def quantity_bytes(q, where):
    m = re.fullmatch(r"(\d+(?:\.\d+)?)(Ki|Mi|Gi|Ti|m|k|M|G|T|)", str(q))
    if not m:
        fail(f"{where}: size {q!r} not understood by this check")
    return float(m.group(1)) * QUANTITY[m.group(2)]


def selects(selector, workload):
    labels = pod_template(workload).get("metadata", {}).get("labels", {}) or {}
    return bool(selector) and all(labels.get(k) == v for k, v in selector.items())


def expand_env(value, c, where):
    """Kubernetes' $(VAR) expansion in args, with the container's env; the namespace from the
    downward API stays as the placeholder <namespace>."""
    env = {}
    for e in c.get("env", []) or []:
        if "value" in e:
            env[e["name"]] = expand_refs(e["value"], env, None)
        elif (e.get("valueFrom", {}).get("fieldRef", {}) or {}).get("fieldPath") == "metadata.namespace":
            env[e["name"]] = "<namespace>"
    return expand_refs(value, env, f"{where}: container {c['name']}")


def expand_refs(value, env, where):
    def sub(m):
        if m.group(1) not in env:
            if where is None:
                return m.group(0)  # env values see only the variables defined before them
            fail(f"{where}: $({m.group(1)}) in {value!r} is not one of its env variables")
        return env[m.group(1)]
    return re.sub(r"\$\((\w+)\)", sub, value)


def int_or_percent(v, total):
    """A PodDisruptionBudget's count; percentages round up, as Kubernetes does."""
    if isinstance(v, str) and v.endswith("%"):
        return -(-total * int(v[:-1]) // 100)
    return int(v)


def check_replicas(label, docs, workloads):
    """The manifests for live viewing across replicas: the shared scene store, readiness that
    reflects load, the PodDisruptionBudget, the HorizontalPodAutoscaler and the gateway's
    dns:/// name of the headless Service."""
    out = []
    claims = {d["metadata"]["name"]: d for d in docs if d["kind"] == "PersistentVolumeClaim"}
    services = {d["metadata"]["name"]: d for d in docs if d["kind"] == "Service"}
    hpas = [d for d in docs if d["kind"] == "HorizontalPodAutoscaler"]
    pdbs = [d for d in docs if d["kind"] == "PodDisruptionBudget"]

    tesserads = []  # (workload, container, flags)
    for w in workloads:
        for c in containers_of(w):
            if c["name"] == "tesserad":
                args = c.get("args", []) or []
                flags = dict(TESSERAD_DEFAULTS)
                flags.update(flag_values(args, "--scene_store_dir", "--scene_store_max_mb",
                                         "--max_sessions", "--shutdown_grace_ms"))
                tesserads.append((w, c, flags))
                if KNOWN_TESSERAD_FLAGS is not None:
                    for a in args:
                        flag = a.partition("=")[0]
                        if flag.startswith("--") and flag[2:] not in KNOWN_TESSERAD_FLAGS:
                            fail(f"{label} {w['kind']}/{w['metadata']['name']}: the tesserad "
                                 f"binary does not know {flag} (an older build? rebuild tesserad)")

    for w, c, flags in tesserads:
        name = f"{label} {w['kind']}/{w['metadata']['name']}"
        hpa = [h for h in hpas if h["spec"].get("scaleTargetRef", {}).get("name") == w["metadata"]["name"]
               and h["spec"]["scaleTargetRef"].get("kind") == w["kind"]]
        replicas = w["spec"].get("replicas", 1 if not hpa else None)
        many = replicas is None or replicas > 1
        count = (f"{replicas} replica{'s' if replicas != 1 else ''}" if replicas is not None
                 else "replicas set by an HPA")
        pod = pod_template(w)["spec"]
        volumes = {v["name"]: v for v in pod.get("volumes", []) or []}

        # The scene store: on a volume every replica mounts read-write.
        store = flags.get("--scene_store_dir")
        if not store:
            if many:
                fail(f"{name}: {count} without --scene_store_dir: a scene uploaded to one replica "
                     "is missing on the others")
            out.append(f"{name}: one replica, no shared scene store")
        else:
            store = store.rstrip("/")
            mounts = [m for m in c.get("volumeMounts", []) or []
                      if store == m["mountPath"].rstrip("/")
                      or store.startswith(m["mountPath"].rstrip("/") + "/")]
            if not mounts:
                fail(f"{name}: --scene_store_dir={store} is in no volume mount of container "
                     "tesserad: replicas would not share it")
            m = max(mounts, key=lambda m: len(m["mountPath"]))
            if m.get("readOnly"):
                fail(f"{name}: --scene_store_dir={store} is on the read-only mount {m['name']}")
            v = volumes[m["name"]]
            max_mb = int(flags["--scene_store_max_mb"])
            if "persistentVolumeClaim" in v:
                cname = v["persistentVolumeClaim"]["claimName"]
                claim = claims[cname]  # existence checked above
                if v["persistentVolumeClaim"].get("readOnly"):
                    fail(f"{name}: --scene_store_dir={store}: claim {cname} is mounted read-only")
                modes = claim["spec"].get("accessModes") or []
                if many and "ReadWriteMany" not in modes:
                    fail(f"{name}: {count} share the scene store on claim {cname}, which is "
                         f"{modes}, not ReadWriteMany")
                size = claim["spec"].get("resources", {}).get("requests", {}).get("storage")
                if not size:
                    fail(f"{name}: claim {cname} requests no storage")
                what = f"claim {cname} ({', '.join(modes)}, {size})"
            elif "emptyDir" in v:
                if many:
                    fail(f"{name}: {count} with --scene_store_dir={store} on emptyDir {m['name']}: "
                         "each replica would have its own store (use a ReadWriteMany claim)")
                size = v["emptyDir"].get("sizeLimit")
                what = f"emptyDir {m['name']} ({size or 'no size limit'})"
            else:
                fail(f"{name}: --scene_store_dir={store} is on volume {m['name']}, neither a "
                     "claim nor an emptyDir")
            if size:
                mib = quantity_bytes(size, name) / 2**20
                if max_mb == 0 or max_mb > 0.9 * mib:
                    fail(f"{name}: --scene_store_max_mb={max_mb} leaves less than 10% of the "
                         f"store's {size} for uploads being written (temporary names)")
            out.append(f"{name}: scene store {store} on {what}, capped at {max_mb} MiB; {count}")

        # Readiness reflects load; liveness and startup ask the server's overall health.
        probes = {p: ((c.get(p) or {}).get("grpc") or {}).get("service", "")
                  for p in ("startupProbe", "readinessProbe", "livenessProbe")}
        if probes["readinessProbe"] != READINESS_SERVICE:
            fail(f"{name}: readinessProbe asks service {probes['readinessProbe']!r}, not "
                 f"{READINESS_SERVICE}: a full replica would stay ready and get new sessions")
        for p in ("startupProbe", "livenessProbe"):
            if probes[p] != "":
                fail(f"{name}: {p} asks service {probes[p]!r}, not \"\" (liveness): a full "
                     "replica would be restarted")
        grace = pod.get("terminationGracePeriodSeconds", 30)
        drain_ms = int(flags["--shutdown_grace_ms"])
        if grace * 1000 < drain_ms + 5000:
            fail(f"{name}: terminationGracePeriodSeconds {grace} does not cover "
                 f"--shutdown_grace_ms={drain_ms} and 5 s for the frame in flight: sessions "
                 "would be killed rather than ended UNAVAILABLE")
        out.append(f"{name}: readiness on {READINESS_SERVICE}, startup and liveness on \"\"; "
                   f"grace {grace} s covers the {drain_ms} ms drain")

        # A PodDisruptionBudget that lets drains proceed one pod at a time.
        mine = [b for b in pdbs if selects((b["spec"].get("selector") or {}).get("matchLabels"), w)]
        if not mine:
            if many:
                fail(f"{name}: no PodDisruptionBudget selects the tesserad pods")
        for b in mine:
            bname = f"{label} PodDisruptionBudget/{b['metadata']['name']}"
            spec = b["spec"]
            if "maxUnavailable" in spec:
                n = int_or_percent(spec["maxUnavailable"], replicas or 1)
                if n < 1:
                    fail(f"{bname}: maxUnavailable {spec['maxUnavailable']} blocks every drain")
                desc = f"maxUnavailable {spec['maxUnavailable']}"
            elif "minAvailable" in spec:
                if replicas is None:
                    fail(f"{bname}: minAvailable with replicas set by an HPA: use maxUnavailable")
                if int_or_percent(spec["minAvailable"], replicas) >= replicas:
                    fail(f"{bname}: minAvailable {spec['minAvailable']} of {replicas} replicas "
                         "blocks every drain")
                desc = f"minAvailable {spec['minAvailable']}"
            else:
                fail(f"{bname}: neither maxUnavailable nor minAvailable")
            out.append(f"{bname}: selects {w['kind']}/{w['metadata']['name']}, {desc}")

        for h in hpa:
            hname = f"{label} HorizontalPodAutoscaler/{h['metadata']['name']}"
            if "replicas" in w["spec"]:
                fail(f"{hname}: {w['kind']}/{w['metadata']['name']} sets spec.replicas: every "
                     "apply would reset what the HPA chose")
            lo, hi = h["spec"].get("minReplicas", 1), h["spec"]["maxReplicas"]
            if not 1 <= lo <= hi:
                fail(f"{hname}: minReplicas {lo}, maxReplicas {hi}")
            for metric in h["spec"].get("metrics", []) or []:
                if metric.get("type") != "Pods":
                    continue
                t = metric["pods"]["target"]
                avg = quantity_bytes(t.get("averageValue", "0"), hname)
                cap = int(flags["--max_sessions"])
                mname = metric["pods"]["metric"]["name"]
                if mname == "tessera_sessions" and not avg < cap:
                    fail(f"{hname}: target {t.get('averageValue')} sessions per pod is not below "
                         f"--max_sessions={cap}: pods would be added only once the replicas are full")
                out.append(f"{hname}: Pods metric {mname}, average {t.get('averageValue')} "
                           f"(--max_sessions={cap}), {lo}..{hi} replicas")

    # Every HPA scales something in this build, and asks a metric an adapter rule here serves.
    rules = {}  # metric name -> ConfigMap
    for d in docs:
        if d["kind"] != "ConfigMap":
            continue
        for key, value in (d.get("data") or {}).items():
            if key.endswith((".yaml", ".yml")):
                doc = yaml.safe_load(value)
                for r in (doc or {}).get("rules", []) if isinstance(doc, dict) else []:
                    if isinstance(r, dict) and "seriesQuery" in r:
                        n = r.get("name") or {}
                        base = re.match(r"[A-Za-z_:][\w:]*", r["seriesQuery"].strip("'\""))
                        rules[n.get("as") or (base.group(0) if base else "")] = d["metadata"]["name"]
    for h in hpas:
        hname = f"{label} HorizontalPodAutoscaler/{h['metadata']['name']}"
        ref = h["spec"].get("scaleTargetRef") or {}
        target = [w for w in workloads if w["kind"] == ref.get("kind")
                  and w["metadata"]["name"] == ref.get("name") and w["apiVersion"] == ref.get("apiVersion")]
        if not target:
            fail(f"{hname}: scaleTargetRef {ref.get('apiVersion')} {ref.get('kind')}/{ref.get('name')} "
                 "is not in this build")
        for metric in h["spec"].get("metrics", []) or []:
            if metric.get("type") in ("Pods", "Object", "External"):
                key = {"Pods": "pods", "Object": "object", "External": "external"}[metric["type"]]
                mname = metric[key]["metric"]["name"]
                if mname not in rules:
                    fail(f"{hname}: metric {mname} is served by no Prometheus adapter rule in this "
                         f"build (rules serve {sorted(rules) or 'nothing'})")
                out.append(f"{hname}: metric {mname} from the adapter rule in ConfigMap/{rules[mname]}")

    # The gateway reaches every replica: dns:/// of a headless Service that selects them.
    for w in workloads:
        for c in containers_of(w):
            if c["name"] != "web":
                continue
            gname = f"{label} {w['kind']}/{w['metadata']['name']}"
            args = c.get("args", []) or []
            env = {e["name"]: e.get("value") for e in c.get("env", []) or []}
            raw = flag_values(args, "--server").get("--server") or env.get("TESSERA_SERVER")
            if not raw:
                fail(f"{gname}: no --server (nor TESSERA_SERVER): the image's default reaches "
                     "one replica only")
            server = expand_env(raw, c, gname)
            if not tesserads:
                continue
            m = re.fullmatch(r"dns:///([^:/]+):(\d+)", server)
            if not m:
                fail(f"{gname}: --server={raw} is not dns:///<headless Service>:<port>: the "
                     "gateway would place every session on the one replica its channel reached")
            host, port = m.group(1), int(m.group(2))
            svc, _, rest = host.partition(".")
            if rest and not re.fullmatch(r"[^.]+(\.svc(\.cluster\.local)?)?", rest):
                fail(f"{gname}: --server={raw}: {host} is not <service>.<namespace>.svc.cluster.local")
            d = services.get(svc)
            if d is None or d["spec"].get("clusterIP") != "None":
                fail(f"{gname}: --server={raw}: {svc} is not a headless Service in this build")
            sname = f"{label} Service/{svc}"
            ws = [t for t, _, _ in tesserads if selects(d["spec"].get("selector"), t)]
            if not ws:
                fail(f"{sname}: the gateway's --server names it, but it selects no tesserad pods")
            sp = [p for p in d["spec"].get("ports", []) if p["port"] == port]
            if not sp:
                fail(f"{gname}: --server={raw}: port {port} is not a port of {sname}")
            tp = sp[0].get("targetPort", port)
            for t, tc, _ in tesserads:
                if t in ws and not any(p.get("name") == "grpc" and tp in (p["name"], p["containerPort"])
                                       for p in tc.get("ports", []) or []):
                    fail(f"{gname}: --server={raw}: {sname} port {port} leads to {tp}, not "
                         "tesserad's grpc port")
            if d["spec"].get("publishNotReadyAddresses"):
                fail(f"{sname}: publishNotReadyAddresses is true: the gateway would see full, "
                     "starting and terminating replicas and place new sessions on them")
            ns = "this pod's namespace" if rest.startswith("<namespace>") else (rest.split(".")[0] or "the gateway's namespace")
            out.append(f"{gname}: --server {server}: headless Service/{svc} ({ns}), port {port} -> "
                       "tesserad's grpc port, unready replicas not published")
    return out


def canonical(docs):
    return sorted(json.dumps(d, sort_keys=True) for d in docs)


def main():
    global KNOWN_TESSERAD_FLAGS
    argv = sys.argv[1:]
    if "--tesserad-flags" in argv:
        i = argv.index("--tesserad-flags")
        with open(argv[i + 1]) as f:
            KNOWN_TESSERAD_FLAGS = {line.strip() for line in f if line.strip()}
        del argv[i:i + 2]
    root = os.path.normpath(argv[0])
    kubectl = argv[1] if len(argv) > 1 else ""
    kfiles = sorted(glob.glob(os.path.join(root, "**", "kustomization.yaml"), recursive=True))
    if not kfiles:
        fail(f"k8s: no kustomization.yaml under {root}")
    used = set()
    for kpath in kfiles:
        directory = os.path.dirname(kpath)
        _, k = read_kustomization(directory)
        if k.get("kind", "Kustomization") == "Component":
            continue
        rel = os.path.relpath(directory, ".")
        docs = build(directory, used)
        for line in check_target(rel, docs):
            print(f"ok    k8s {line}")
        images = sorted({c["image"] for d in docs for c in containers_of(d)})
        kinds = ", ".join(f"{d['kind']}/{d['metadata']['name']}" for d in docs)
        print(f"ok    k8s {rel}: builds {len(docs)} objects ({kinds}); images {', '.join(images)}")
        if kubectl:
            r = subprocess.run([kubectl, "kustomize", directory], capture_output=True, text=True,
                               timeout=120)
            if r.returncode != 0:
                fail(f"kubectl kustomize {rel}: {r.stderr.strip()}")
            ref = [d for d in yaml.safe_load_all(r.stdout) if d]
            if canonical(ref) != canonical(docs):
                mine = {(d["kind"], d["metadata"]["name"]): d for d in docs}
                for d in ref:
                    m = mine.get((d["kind"], d["metadata"]["name"]))
                    if m != d:
                        diff = jsonpatch.make_patch(m or {}, d).patch
                        fail(f"kubectl kustomize {rel} differs from this build at "
                             f"{d['kind']}/{d['metadata']['name']}: {diff[:4]}")
                fail(f"kubectl kustomize {rel} differs from this build (objects missing)")
            print(f"ok    k8s {rel}: kubectl kustomize builds the same {len(ref)} objects")
    files = {os.path.normpath(p) for p in glob.glob(os.path.join(root, "**", "*.y*ml"), recursive=True)}
    stale = sorted(files - used)
    if stale:
        fail(f"k8s: {stale} used by no kustomization (add them to one, or remove them)")
    print(f"ok    k8s every one of the {len(files)} YAML files under {root} is used by a kustomization")


if __name__ == "__main__":
    try:
        main()
    except Failure as e:
        print(f"FAIL  {e}")
        sys.exit(1)
