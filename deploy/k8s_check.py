#!/usr/bin/env python3
"""Builds every kustomization under deploy/k8s and checks what each would apply.

Run by deploy/validate.sh; usage: k8s_check.py ROOT [KUBECTL]

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
  - ConfigMap data named *.json parses.
And for the tree: every YAML file under ROOT is used by some kustomization (nothing stale).
"""
import copy
import glob
import json
import os
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
    return out


def canonical(docs):
    return sorted(json.dumps(d, sort_keys=True) for d in docs)


def main():
    root = os.path.normpath(sys.argv[1])
    kubectl = sys.argv[2] if len(sys.argv) > 2 else ""
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
