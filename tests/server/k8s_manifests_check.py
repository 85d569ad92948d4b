"""Offline check of the Kubernetes manifests in deploy/k8s (docs/cluster.md).

No cluster runs them here, and kubectl's client-side dry run still asks an API server for its
resource types (Debian 12's kubectl 1.20 fails with "connection refused" without one), so each
document is checked against the Kubernetes API's own schema as Debian's python3-kubernetes
(22.6: the Kubernetes 1.22 API, which has Indexed Jobs) generates it:
  - every field is one the API knows, at every depth, with the JSON type it declares (the models'
    attribute_map and openapi_types); a misspelt or misplaced field fails;
  - the document deserializes into the typed model, whose constructors refuse missing required
    fields (a container without a name or image, a Service port without a port...);
and then for what makes these manifests work together: the Deployment's pods carry the labels
its selector and the Service select, every claim a pod mounts is declared, the shard Job is
Indexed with as many pods at once as completions and passes JOB_COMPLETION_INDEX to
`probebake bake --shard`, and the merge reads exactly the parts the shards write.

  python3 k8s_manifests_check.py DEPLOY_K8S_DIR [--self-test]
With --self-test, it also checks that it catches a misspelt field, a missing required field and a
merge of the wrong parts in altered copies of the manifests.
Exit 0 when every check passes, 1 with the problems listed, 77 (skipped) without
python3-kubernetes or python3-yaml.
"""

import json
import os
import re
import sys

try:
    import yaml
    from kubernetes import client
except ImportError as e:  # pragma: no cover - depends on the machine
    print(f"SKIPPED: {e.name} is not installed (Debian: apt-get install python3-kubernetes)")
    sys.exit(77)

MODELS = {
    ("v1", "PersistentVolumeClaim"): "V1PersistentVolumeClaim",
    ("v1", "Service"): "V1Service",
    ("apps/v1", "Deployment"): "V1Deployment",
    ("batch/v1", "Job"): "V1Job",
}
PRIMITIVES = {"str": str, "int": int, "bool": bool, "float": (int, float)}


def check_fields(value, type_name, path, problems):
    """Walks `value` alongside the model type `type_name`, noting unknown or mistyped fields."""
    if type_name == "object":  # IntOrString, Quantity, free-form
        return
    if type_name in PRIMITIVES:
        expected = PRIMITIVES[type_name]
        if isinstance(value, bool) and type_name != "bool":
            problems.append(f"{path}: expected {type_name}, got a boolean")
        elif not isinstance(value, expected):
            problems.append(f"{path}: expected {type_name}, got {type(value).__name__}")
        return
    if type_name == "datetime":
        return
    m = re.fullmatch(r"list\[(.+)\]", type_name)
    if m:
        if not isinstance(value, list):
            problems.append(f"{path}: expected a list")
            return
        for i, item in enumerate(value):
            check_fields(item, m.group(1), f"{path}[{i}]", problems)
        return
    m = re.fullmatch(r"dict\(str, (.+)\)", type_name)
    if m:
        if not isinstance(value, dict):
            problems.append(f"{path}: expected a map")
            return
        for key, item in value.items():
            check_fields(item, m.group(1), f"{path}.{key}", problems)
        return
    model = getattr(client, type_name)
    if not isinstance(value, dict):
        problems.append(f"{path}: expected an object ({type_name})")
        return
    by_json = {json_name: attr for attr, json_name in model.attribute_map.items()}
    for key, item in value.items():
        if key not in by_json:
            problems.append(f"{path}.{key}: not a field of {type_name}")
            continue
        check_fields(item, model.openapi_types[by_json[key]], f"{path}.{key}", problems)


def check_document(doc, where, problems):
    key = (doc.get("apiVersion"), doc.get("kind"))
    if key not in MODELS:
        problems.append(f"{where}: no schema here for {key[0]} {key[1]}")
        return None
    before = len(problems)
    check_fields(doc, MODELS[key], where, problems)
    if len(problems) == before:
        try:
            api = client.ApiClient()
            api._ApiClient__deserialize(doc, MODELS[key])  # required fields checked here
        except (ValueError, TypeError) as e:
            problems.append(f"{where}: {e}")
    if not doc.get("metadata", {}).get("name"):
        problems.append(f"{where}: metadata.name is required")
    return key


def pod_spec(doc):
    return doc["spec"]["template"]["spec"]


def script_of(doc):
    return " ".join(" ".join(c.get("command", []) + c.get("args", []))
                    for c in pod_spec(doc)["containers"])


def check_together(docs, problems):
    by_kind = {}
    for where, doc in docs:
        by_kind.setdefault(doc["kind"], []).append((where, doc))
    claims = {doc["metadata"]["name"] for _, doc in by_kind.get("PersistentVolumeClaim", [])}
    for kind in ("Deployment", "Job"):
        for where, doc in by_kind.get(kind, []):
            for volume in pod_spec(doc).get("volumes", []):
                claim = volume.get("persistentVolumeClaim", {}).get("claimName")
                if claim and claim not in claims:
                    problems.append(f"{where}: mounts claim {claim}, declared nowhere")
    for where, doc in by_kind.get("Deployment", []):
        labels = doc["spec"]["template"]["metadata"].get("labels", {})
        selector = doc["spec"]["selector"].get("matchLabels", {})
        if any(labels.get(k) != v for k, v in selector.items()):
            problems.append(f"{where}: the selector does not select the pods' labels")
        for s_where, service in by_kind.get("Service", []):
            if any(labels.get(k) != v for k, v in service["spec"].get("selector", {}).items()):
                problems.append(f"{s_where}: selects no pod of {where}")
    jobs = {doc["metadata"]["name"]: (where, doc) for where, doc in by_kind.get("Job", [])}
    shards = jobs.get("probebake-shards")
    merge = jobs.get("probebake-merge")
    if not shards or not merge:
        problems.append("the Jobs probebake-shards and probebake-merge are required")
        return
    where, doc = shards
    spec = doc["spec"]
    if spec.get("completionMode") != "Indexed":
        problems.append(f"{where}: completionMode must be Indexed")
    n = spec.get("completions")
    if not isinstance(n, int) or spec.get("parallelism") != n:
        problems.append(f"{where}: completions and parallelism must be the shard count")
    script = script_of(doc)
    if f'--shard "$JOB_COMPLETION_INDEX/{n}"' not in script:
        problems.append(f"{where}: the pods must bake --shard \"$JOB_COMPLETION_INDEX/{n}\"")
    if "part-$JOB_COMPLETION_INDEX.vdb" not in script:
        problems.append(f"{where}: each pod must write part-$JOB_COMPLETION_INDEX.vdb")
    merged = re.findall(r"part-(\d+)\.vdb", script_of(merge[1]))
    if sorted(int(i) for i in merged) != list(range(n if isinstance(n, int) else 0)):
        problems.append(f"{merge[0]}: must merge parts 0 to {n}-1 exactly, merges {merged}")


def load(folder):
    """(where, document) of every YAML document in `folder`, in file name order."""
    docs = []
    for name in sorted(os.listdir(folder)):
        if not name.endswith(".yaml"):
            continue
        with open(os.path.join(folder, name)) as f:
            for i, doc in enumerate(yaml.safe_load_all(f)):
                if doc is not None:
                    docs.append((f"{name}[{i}] {doc.get('kind')}", doc))
    return docs


def problems_of(loaded):
    problems, docs = [], []
    for where, doc in loaded:
        if check_document(doc, where, problems):
            docs.append((where, doc))
    if not problems:
        check_together(docs, problems)
    return problems


def self_test(loaded):
    """Altered copies of the manifests, each of which must be refused."""
    def job(docs, name):
        return next(d for _, d in docs if d.get("metadata", {}).get("name") == name)

    def misspelt(docs):
        spec = job(docs, "probebake-shards")["spec"]
        spec["completionMod"] = spec.pop("completionMode")

    def nameless(docs):
        del pod_spec(job(docs, "probebake-merge"))["containers"][0]["name"]

    def wrong_parts(docs):
        c = pod_spec(job(docs, "probebake-merge"))["containers"][0]
        c["command"] = [part.replace("part-3", "part-5") for part in c["command"]]

    failures = []
    for alter in (misspelt, nameless, wrong_parts):
        docs = json.loads(json.dumps(loaded))
        alter(docs)
        if not problems_of(docs):
            failures.append(f"self-test: {alter.__name__} manifests were not refused")
    return failures


def main():
    loaded = load(sys.argv[1])
    problems = problems_of(loaded)
    if "--self-test" in sys.argv[2:]:
        problems += self_test(loaded)
    for p in problems:
        print(p)
    print(json.dumps({"documents": len(loaded), "problems": len(problems)}))
    sys.exit(1 if problems else 0)


if __name__ == "__main__":
    main()
