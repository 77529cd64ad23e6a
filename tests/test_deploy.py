"""deploy/k8s: what the manifests promise, checked against the service itself (app/settings.py, the routes
the app serves, the Dockerfile), so that a change on either side that breaks the other fails here.

No cluster and no network: the manifests are read as YAML (and rendered with ``kubectl kustomize`` where
kubectl is installed). ``.ci/k8s.sh`` also validates them against the Kubernetes schemas, scans them with
checkov and runs their pod under a read-only root (``.ci/k8s_pod.py``).
"""

from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest
import yaml

from app import settings as settings_module
from app.main import app_routers, create_app
from app.routes.health import READY_TIMEOUT_S
from app.settings import Settings

ROOT = Path(__file__).resolve().parents[1]
K8S = ROOT / "deploy" / "k8s"
OVERLAY = ROOT / "deploy" / "overlay-example"
#: the label every resource carries and every selector uses
NAME_LABEL = "app.kubernetes.io/name"
#: memory of a pod's processes that KAPPA_MAX_PROCESS_RSS_MB does not bound: the supervisor (python -m
#: app, ~42 MiB here) and multiprocessing's resource tracker (~13 MiB), with room [MiB]
UNBOUNDED_MIB = 100

Manifest = dict[str, Any]


def load(path: Path) -> Manifest:
    documents = [d for d in yaml.safe_load_all(path.read_text()) if d]
    assert len(documents) == 1, f"{path.name}: one resource per file"
    manifest: Manifest = documents[0]
    return manifest


def kustomization() -> Manifest:
    return load(K8S / "kustomization.yaml")


def resources() -> dict[str, Manifest]:
    """kind → the resource, for every file the kustomization lists."""
    found = [load(K8S / name) for name in kustomization()["resources"]]
    by_kind = {m["kind"]: m for m in found}
    assert len(by_kind) == len(found), "one resource of each kind"
    return by_kind


def pod_spec() -> Manifest:
    spec: Manifest = resources()["Deployment"]["spec"]["template"]["spec"]
    return spec


def container() -> Manifest:
    (only,) = pod_spec()["containers"]
    c: Manifest = only
    return c


def pod_env() -> dict[str, str]:
    """The container's environment: its plain values (one from elsewhere, such as a Secret, left out)."""
    return {e["name"]: str(e["value"]) for e in container().get("env", []) if "value" in e}


@pytest.fixture
def settings(monkeypatch: pytest.MonkeyPatch) -> Settings:
    """The service's settings in the pod: its environment alone (none of this process's KAPPA_*)."""
    for name in list(os.environ):
        if name.startswith("KAPPA_"):
            monkeypatch.delenv(name)
    for name, value in pod_env().items():
        monkeypatch.setenv(name, value)
    return Settings()


def cpus(quantity: str | int) -> float:
    """A Kubernetes CPU quantity (``2``, ``1500m``) in CPUs."""
    text = str(quantity)
    return int(text[:-1]) / 1000 if text.endswith("m") else float(text)


def mebibytes(quantity: str | int) -> float:
    """A Kubernetes memory quantity (``2Gi``, ``512Mi``, ``1G``, bytes) in MiB."""
    match = re.fullmatch(r"(\d+(?:\.\d+)?)(Ki|Mi|Gi|k|M|G)?", str(quantity))
    assert match, quantity
    factor = {None: 1, "Ki": 2**10, "Mi": 2**20, "Gi": 2**30, "k": 1e3, "M": 1e6, "G": 1e9}[match.group(2)]
    return float(match.group(1)) * factor / 2**20


def container_port(name: str) -> int:
    (port,) = [p["containerPort"] for p in container()["ports"] if p["name"] == name]
    return int(port)


def test_the_kustomization_lists_every_manifest_and_each_carries_the_label() -> None:
    listed = kustomization()["resources"]
    on_disk = sorted(p.name for p in K8S.glob("[!.]*.yaml") if p.name != "kustomization.yaml")
    assert sorted(listed) == on_disk
    assert set(resources()) == {
        "Deployment",
        "Service",
        "HorizontalPodAutoscaler",
        "PodDisruptionBudget",
        "NetworkPolicy",
    }
    for manifest in resources().values():
        assert manifest["metadata"]["labels"][NAME_LABEL] == "kappa-planner"
        assert "namespace" not in manifest["metadata"]  # chosen by the deployer (-n, an overlay)


def test_the_probes_ask_the_routes_the_service_has_on_its_port(settings: Settings) -> None:
    app = create_app(settings)
    served = {r.path for router in app_routers(app) for r in router.routes if "GET" in r.methods}
    assert "/metrics" not in served  # on KAPPA_METRICS_PORT only (test_metrics_are_scraped_on_their_own_port)
    c = container()
    probes = {name: c[name]["httpGet"] for name in ("startupProbe", "livenessProbe", "readinessProbe")}
    assert probes["livenessProbe"]["path"] == probes["startupProbe"]["path"] == "/healthz"
    assert probes["readinessProbe"]["path"] == "/readyz"
    for get in probes.values():
        assert get["path"] in served
        assert container_port(get["port"]) == settings.port
    # readiness waits up to READY_TIMEOUT_S for an idle plan process: the kubelet must wait longer
    assert c["readinessProbe"]["timeoutSeconds"] > READY_TIMEOUT_S
    # the startup probe gives the plan processes time to plan the demo (10-30 s seen on 2 CPUs)
    startup = c["startupProbe"]
    assert startup["periodSeconds"] * startup["failureThreshold"] >= 60


def test_the_grace_period_outlasts_the_pre_stop_hook_and_the_service_s_own_shutdown(
    settings: Settings,
) -> None:
    command = container()["lifecycle"]["preStop"]["exec"]["command"]
    assert command[0] == "sleep" and len(command) == 2
    pre_stop_s = float(command[1])
    grace_s = pod_spec()["terminationGracePeriodSeconds"]
    assert settings.shutdown_timeout >= Settings.model_fields["shutdown_timeout"].default
    assert grace_s > pre_stop_s + settings.shutdown_timeout + 1


def test_the_cpu_limit_holds_one_plan_process_per_cpu(
    settings: Settings, monkeypatch: pytest.MonkeyPatch
) -> None:
    resources_ = container()["resources"]
    limit, request = cpus(resources_["limits"]["cpu"]), cpus(resources_["requests"]["cpu"])
    assert request == limit  # the HPA's utilisation is of the request: busy plan processes read as 100 %
    assert settings.workers * settings.plan_pool_size() == math.ceil(limit)
    # KAPPA_PLAN_PROCESSES set or not, the pool is the same in the pod: unset, CPUs ÷ workers with the
    # CPUs capped by the cgroup quota the CPU limit sets (on a node of many CPUs)
    monkeypatch.delenv("KAPPA_PLAN_PROCESSES", raising=False)
    monkeypatch.setattr(settings_module, "cgroup_cpu_limit", lambda: limit)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(64)), raising=False)
    assert Settings().plan_pool_size() == settings.plan_pool_size()


def test_the_memory_limit_holds_every_process_at_its_replacement_threshold(settings: Settings) -> None:
    resources_ = container()["resources"]
    limit, request = mebibytes(resources_["limits"]["memory"]), mebibytes(resources_["requests"]["memory"])
    processes = settings.workers * (1 + settings.plan_pool_size())  # each worker and its plan processes
    assert limit >= processes * settings.max_process_rss_mb + UNBOUNDED_MIB
    assert request <= limit


def test_the_pod_runs_unprivileged_as_the_image_s_user() -> None:
    dockerfile = (ROOT / "Dockerfile").read_text()
    (user,) = re.findall(r"^USER\s+(\d+):(\d+)\s*$", dockerfile, flags=re.MULTILINE)
    spec, context = pod_spec(), container()["securityContext"]
    assert spec["automountServiceAccountToken"] is False
    assert spec["securityContext"]["runAsNonRoot"] is True
    assert (spec["securityContext"]["runAsUser"], spec["securityContext"]["runAsGroup"]) == tuple(
        map(int, user)
    )
    assert spec["securityContext"]["seccompProfile"] == {"type": "RuntimeDefault"}
    assert context["allowPrivilegeEscalation"] is False
    assert context["privileged"] is False
    assert context["readOnlyRootFilesystem"] is True
    assert context["capabilities"] == {"drop": ["ALL"]}
    assert context.get("runAsUser", spec["securityContext"]["runAsUser"]) == int(user[0])
    assert "hostNetwork" not in spec and "hostPID" not in spec


def test_every_place_the_service_writes_is_an_empty_dir() -> None:
    """The root filesystem is read-only: the metrics' multiprocess directory (app/__main__.py) and Python's
    temporary directory must be on emptyDir volumes, and Python must not write bytecode."""
    volumes = {v["name"]: v for v in pod_spec()["volumes"]}
    writable = [Path(m["mountPath"]) for m in container()["volumeMounts"] if "emptyDir" in volumes[m["name"]]]
    env = pod_env()
    assert Path(env["PROMETHEUS_MULTIPROC_DIR"]).is_absolute()
    temporary = Path(env.get("TMPDIR", "/tmp"))
    for path in (Path(env["PROMETHEUS_MULTIPROC_DIR"]), temporary):
        assert any(path.is_relative_to(w) for w in writable), f"{path} is on the read-only root"
    assert all(v.get("emptyDir", {}).get("sizeLimit") for v in volumes.values())
    assert re.search(r"^\s+PYTHONDONTWRITEBYTECODE=1", (ROOT / "Dockerfile").read_text(), flags=re.MULTILINE)


def test_metrics_are_scraped_on_their_own_port(settings: Settings) -> None:
    annotations = resources()["Deployment"]["spec"]["template"]["metadata"]["annotations"]
    assert annotations["prometheus.io/scrape"] == "true"
    assert int(annotations["prometheus.io/port"]) == settings.metrics_port == container_port("metrics")
    assert annotations["prometheus.io/path"] == "/metrics"
    assert settings.metrics_port != settings.port
    ingress_ports = {
        p["port"] for rule in resources()["NetworkPolicy"]["spec"]["ingress"] for p in rule["ports"]
    }
    assert ingress_ports == {"http", "metrics"}


def test_service_autoscaler_and_disruption_budget_select_the_deployment_s_pods() -> None:
    by_kind = resources()
    deployment = by_kind["Deployment"]
    labels = deployment["spec"]["template"]["metadata"]["labels"]
    assert deployment["spec"]["selector"]["matchLabels"].items() <= labels.items()
    assert "replicas" not in deployment["spec"]  # the autoscaler owns the count

    service = by_kind["Service"]
    assert service["spec"]["selector"].items() <= labels.items()
    assert [p["targetPort"] for p in service["spec"]["ports"]] == ["http"]
    assert "sessionAffinity" not in service["spec"]  # stateless: any pod answers any request

    hpa = by_kind["HorizontalPodAutoscaler"]
    assert hpa["apiVersion"] == "autoscaling/v2"
    target = hpa["spec"]["scaleTargetRef"]
    assert (target["kind"], target["name"]) == ("Deployment", deployment["metadata"]["name"])
    (metric,) = hpa["spec"]["metrics"]
    assert metric["resource"]["name"] == "cpu" and metric["resource"]["target"]["type"] == "Utilization"
    assert 2 <= hpa["spec"]["minReplicas"] <= hpa["spec"]["maxReplicas"]

    pdb = by_kind["PodDisruptionBudget"]
    assert pdb["spec"]["selector"]["matchLabels"].items() <= labels.items()
    assert pdb["spec"]["maxUnavailable"] < hpa["spec"]["minReplicas"]  # one pod serves during a drain
    assert by_kind["NetworkPolicy"]["spec"]["podSelector"]["matchLabels"].items() <= labels.items()


def test_every_checkov_skip_gives_its_reason() -> None:
    lines = (K8S / ".checkov.yaml").read_text().splitlines()
    skips = yaml.safe_load("\n".join(lines))["skip-check"]
    assert skips
    for skip in skips:
        (at,) = [i for i, line in enumerate(lines) if line.strip() == f"- {skip}"]
        block = [line.strip() for line in lines[:at]][::-1]
        reason = next(i for i, line in enumerate(block) if not line.startswith("- "))
        assert block[reason].startswith("#"), f"{skip}: no comment giving its reason above it"


def kubectl() -> str | None:
    local = ROOT / ".venv-k8s" / "bin" / "kubectl"  # .ci/k8s.sh installs it there
    return shutil.which("kubectl") or (str(local) if local.exists() else None)


@pytest.mark.skipif(kubectl() is None, reason="no kubectl here (.ci/k8s.sh installs one and renders)")
def test_kubectl_renders_the_base_and_the_example_overlay() -> None:
    def render(folder: Path) -> list[Manifest]:
        done = subprocess.run(
            [str(kubectl()), "kustomize", str(folder)], capture_output=True, text=True, timeout=60, check=True
        )
        return [d for d in yaml.safe_load_all(done.stdout) if d]

    base = render(K8S)
    assert sorted((m["kind"], m["metadata"]["name"]) for m in base) == sorted(
        (m["kind"], m["metadata"]["name"]) for m in resources().values()
    )
    overlay = render(OVERLAY)
    assert {m["metadata"].get("namespace") for m in overlay} == {"kappa-planner"}
    (deployment,) = [m for m in overlay if m["kind"] == "Deployment"]
    image = deployment["spec"]["template"]["spec"]["containers"][0]["image"]
    assert re.fullmatch(r"[\w.-]+(/[\w.-]+)+@sha256:[0-9a-f]{64}", image), image
