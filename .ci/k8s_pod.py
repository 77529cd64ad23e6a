"""Run the pod of deploy/k8s's Deployment without a cluster, as the kubelet would, and check it works.

    python .ci/k8s_pod.py RENDERED.yaml    # the output of `kubectl kustomize deploy/k8s`

What is read from the rendered Deployment (its one container) rather than repeated here, so that a change
there is what runs here:

* the environment: the image's (the final stage's ``ENV`` of the ``Dockerfile``, read as
  ``.ci/dockerfile_replay.py`` reads it) and the container's ``env`` on top, the port variables
  overridden with free ports on 127.0.0.1 (nothing listens beyond this machine);
* the filesystem: the root filesystem read-only (``readOnlyRootFilesystem``, checked to be set) and an
  empty tmpfs of the volume's ``sizeLimit`` at every ``mountPath`` of an ``emptyDir`` volume — the only
  places the service may write, with ``/dev/shm`` (the container runtime mounts one writable);
* the privileges: no capabilities at all (``capabilities.drop: [ALL]``) and no new privileges
  (``allowPrivilegeEscalation: false``);
* the probes: the startup probe within its ``failureThreshold × periodSeconds``, then readiness and
  liveness, each with its own timeout; the container port named by each probe must be the port the
  service listens on (``KAPPA_PORT``);
* the metrics: the pod's ``prometheus.io/port`` and ``prometheus.io/path`` annotations scraped, and
  they must count the plan posted meanwhile (the multiprocess directory works in its ``emptyDir``);
* the stop: the ``preStop`` command run (the service must stay ready meanwhile), then SIGTERM; the
  service must exit 0 within ``terminationGracePeriodSeconds`` less the time the hook took.

Not replayed, and why: the image itself (this interpreter and the project installed in it stand for it;
``.ci/container.sh`` replays the image's build), the user (the process keeps uid 0, without any
capability: CI's interpreter lives under /root, which uid 10001 cannot read; the read-only root is
enforced by the mount whatever the uid), seccomp, and the CPU and memory limits (``bench/load.py
--replicas`` measures what a replica's share of the CPUs does).

Linux only, as root (a mount namespace of its own: ``unshare``, ``mount``, ``setpriv`` of util-linux).
Exit status: 0 when everything passed; else 1 with the reason and the server's log.
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
# the Dockerfile read, and the service probed, one way only
from dockerfile_replay import ReplayError, env_pairs, free_port, http, plan_demo, stages

ROOT = Path(__file__).resolve().parents[1]
#: variables passed from this environment to the server (see env/README: OpenBLAS needs them here)
PASS_THROUGH = ("OPENBLAS_CORETYPE", "OPENBLAS_L2_SIZE")
#: what the server's log must never say (a write refused, a crash)
BAD_LOG = re.compile(r"Read-only file system|Permission denied|Traceback|No usable temporary directory")


class PodError(ReplayError):
    """The pod cannot be replayed, or it did not behave."""


def say(message: str) -> None:
    print(message, flush=True)


@dataclass
class Pod:
    """What the replay needs of the rendered Deployment."""

    container: dict[str, Any]
    annotations: dict[str, str]
    volumes: dict[str, dict[str, Any]]
    grace_s: float

    def port(self, name_or_number: str | int) -> int:
        """The container port a probe names (by name or number)."""
        for port in self.container.get("ports", []):
            if name_or_number in (port.get("name"), port["containerPort"]):
                return int(port["containerPort"])
        raise PodError(f"the container has no port {name_or_number!r}")


def read_pod(rendered: Path) -> Pod:
    documents = [d for d in yaml.safe_load_all(rendered.read_text()) if d]
    deployments = [d for d in documents if d.get("kind") == "Deployment"]
    if len(deployments) != 1:
        raise PodError(f"expected one Deployment in {rendered}, found {len(deployments)}")
    spec = deployments[0]["spec"]["template"]
    containers = spec["spec"]["containers"]
    if len(containers) != 1 or spec["spec"].get("initContainers"):
        raise PodError("the replay knows pods of one container and no init container")
    return Pod(
        container=containers[0],
        annotations=spec.get("metadata", {}).get("annotations", {}),
        volumes={v["name"]: v for v in spec["spec"].get("volumes", [])},
        grace_s=float(spec["spec"].get("terminationGracePeriodSeconds", 30)),
    )


def image_runtime(dockerfile: Path) -> tuple[dict[str, str], list[str]]:
    """The final stage's ``ENV`` (``PATH`` and ``VIRTUAL_ENV`` mapped to this interpreter's) and ``CMD``."""
    final = stages(dockerfile)[0][-1]
    env: dict[str, str] = {"VIRTUAL_ENV": sys.prefix, "PATH": os.environ["PATH"]}
    cmd: list[str] | None = None
    for command in final.commands:
        if command.cmd == "ENV":
            for name, value in env_pairs(command, env):
                if name not in ("PATH", "VIRTUAL_ENV"):
                    env[name] = value
        elif command.cmd == "CMD":
            if not command.json:
                raise PodError("the Dockerfile's CMD is not in exec form")
            cmd = list(command.value)
        elif command.cmd == "ENTRYPOINT":
            raise PodError("the replay knows a CMD without ENTRYPOINT")
    if cmd is None:
        raise PodError("the Dockerfile's final stage has no CMD")
    env["PATH"] = f"{Path(sys.prefix) / 'bin'}:{os.environ['PATH']}"
    return env, cmd


def quantity_bytes(quantity: str) -> int:
    """A Kubernetes memory quantity (``64Mi``, ``1G``, ``512``) in bytes."""
    units = {"": 1, "k": 10**3, "M": 10**6, "G": 10**9, "Ki": 2**10, "Mi": 2**20, "Gi": 2**30}
    match = re.fullmatch(r"(\d+)([kMG]i?|Ki)?", str(quantity))
    if not match:
        raise PodError(f"cannot read the quantity {quantity!r}")
    return int(match.group(1)) * units[match.group(2) or ""]


def writable_mounts(pod: Pod) -> list[tuple[int, str]]:
    """(size [bytes], path) of every emptyDir the container mounts."""
    mounts = []
    for mount in pod.container.get("volumeMounts", []):
        volume = pod.volumes.get(mount["name"])
        if volume is None or "emptyDir" not in volume:
            raise PodError(f"volume {mount['name']!r}: the replay knows emptyDir volumes only")
        if mount.get("subPath") or mount.get("readOnly"):
            raise PodError(f"volume {mount['name']!r}: subPath and readOnly are not replayed")
        if not Path(mount["mountPath"]).is_dir():
            raise PodError(f"{mount['mountPath']} does not exist here to mount the emptyDir on")
        size = quantity_bytes((volume["emptyDir"] or {}).get("sizeLimit", "64Mi"))
        mounts.append((size, mount["mountPath"]))
    return mounts


def check_security_context(pod: Pod) -> None:
    """The fields the replay relies on (it enforces them; the manifest must ask for them)."""
    context = pod.container.get("securityContext", {})
    if context.get("readOnlyRootFilesystem") is not True:
        raise PodError("the container's root filesystem is not read-only")
    if context.get("allowPrivilegeEscalation") is not False:
        raise PodError("the container may escalate privileges")
    if context.get("capabilities", {}).get("drop") != ["ALL"] or context["capabilities"].get("add"):
        raise PodError("the container does not drop every capability")


def status_of(url: str, timeout: float) -> int:
    """The status of a GET of ``url`` (0: no answer), as a probe sees it."""
    try:
        return http(url, timeout=timeout)[0]
    except OSError:
        return 0


def probe_url(pod: Pod, probe: dict[str, Any], host_ports: dict[int, int]) -> tuple[str, float]:
    """The URL of an HTTP probe on this machine, and its timeout [s]."""
    get = probe.get("httpGet")
    if get is None:
        raise PodError(f"only httpGet probes are replayed: {probe}")
    container_port = pod.port(get["port"])
    if container_port not in host_ports:
        raise PodError(f"the probe's port {get['port']} ({container_port}) is not the service's")
    return f"http://127.0.0.1:{host_ports[container_port]}{get['path']}", float(
        probe.get("timeoutSeconds", 1)
    )


def until_ok(url: str, timeout: float, within: float, server: subprocess.Popen[bytes]) -> float:
    """Probe ``url`` until it answers 200 (each try ``timeout`` s) or ``within`` s pass; the time taken."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < within:
        if server.poll() is not None:
            raise PodError(f"the server exited with {server.returncode} before {url} answered")
        if status_of(url, timeout) == 200:
            return time.monotonic() - t0
        time.sleep(0.2)
    raise PodError(f"{url} did not answer 200 within {within:g} s")


def replay(rendered: Path, scratch: Path) -> None:
    pod = read_pod(rendered)
    check_security_context(pod)
    mounts = writable_mounts(pod)
    env, cmd = image_runtime(ROOT / "Dockerfile")
    if pod.container.get("command") or pod.container.get("args"):
        raise PodError("the container overrides the image's command: the replay runs the image's CMD")
    for item in pod.container.get("env", []):
        if "value" not in item:
            continue  # valueFrom (a Secret, the downward API): none is needed to serve
        env[item["name"]] = str(item["value"])
    env.update({k: os.environ[k] for k in PASS_THROUGH if k in os.environ})
    env["HOME"] = "/nonexistent"  # the image user's home: there is none
    # the service's ports, as the container declares them, moved to free ones on the loopback
    host_ports = {int(env["KAPPA_PORT"]): free_port()}
    env["KAPPA_HOST"], env["KAPPA_PORT"] = "127.0.0.1", str(host_ports[int(env["KAPPA_PORT"])])
    if env.get("KAPPA_METRICS_PORT", "0") not in ("", "0"):
        host_ports[int(env["KAPPA_METRICS_PORT"])] = free_port()
        env["KAPPA_METRICS_PORT"] = str(host_ports[int(env["KAPPA_METRICS_PORT"])])
    workdir = scratch / "workdir"  # empty, and read-only once the root is
    workdir.mkdir()
    say(f"-- image command {shlex.join(cmd)}, env from the Dockerfile and the Deployment:")
    say(
        "   "
        + " ".join(f"{k}={v}" for k, v in sorted(env.items()) if k.startswith(("KAPPA_", "PROM", "PYTHON")))
    )
    say(
        f"-- read-only root; writable: {', '.join(f'{p} (tmpfs {s >> 20} MiB)' for s, p in mounts)}, /dev/shm"
    )

    log_path = scratch / "server.log"
    # what the mounts would hide but the server needs (the repository, this interpreter, the working
    # directory when they lie under an emptyDir's path, e.g. a clone in /tmp): bound back, read-only
    needed = sorted({ROOT, Path(sys.prefix), Path(sys.base_prefix), workdir})
    keep = [p for p in needed if any(p.is_relative_to(m) for _, m in mounts)]
    keep = [p for p in keep if not any(p != q and p.is_relative_to(q) for q in keep)]
    argv = [sys.executable, __file__, "--inside", str(workdir)]  # then main() calls inside()
    argv += [f"--mount={size}:{path}" for size, path in mounts] + [f"--keep={p}" for p in keep]
    argv = ["unshare", "--mount", *argv, "--", *cmd]
    with log_path.open("wb") as log:
        server = subprocess.Popen(argv, env=env, stdout=log, stderr=subprocess.STDOUT)
    try:
        run_pod(pod, server, host_ports, env, keep)
    except ReplayError:
        tail = log_path.read_text(errors="replace").splitlines()[-60:]
        say("-- server log (last 60 lines)\n" + "\n".join(tail))
        raise
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()
    bad = [line for line in log_path.read_text(errors="replace").splitlines() if BAD_LOG.search(line)]
    if bad:
        raise PodError("the server's log reports:\n" + "\n".join(bad[:20]))


def run_pod(
    pod: Pod,
    server: subprocess.Popen[bytes],
    host_ports: dict[int, int],
    env: dict[str, str],
    keep: list[Path],
) -> None:
    """Probe the server as the kubelet would, plan the demo, scrape its metrics, look at the process and
    what it wrote, stop it."""
    startup = pod.container.get("startupProbe") or pod.container["livenessProbe"]
    url, timeout = probe_url(pod, startup, host_ports)
    within = float(startup.get("initialDelaySeconds", 0))
    within += float(startup.get("failureThreshold", 3)) * float(startup.get("periodSeconds", 10))
    took = until_ok(url, timeout, within, server)
    say(f"-- startup probe {url}: 200 after {took:.1f} s (allowed {within:g} s)")
    for name in ("readinessProbe", "livenessProbe"):
        url, timeout = probe_url(pod, pod.container[name], host_ports)
        took = until_ok(url, timeout, 30.0, server)
        say(f"-- {name} {url}: 200 after {took:.1f} s more")

    plan_demo(f"http://127.0.0.1:{env['KAPPA_PORT']}")
    say("-- POST /v1/plan (the demo): 200, status ok")
    scrape(pod, host_ports)

    fields = dict(
        line.split(":\t", 1)
        for line in Path(f"/proc/{server.pid}/status").read_text().splitlines()
        if ":\t" in line
    )
    if int(fields["CapEff"], 16) or int(fields["CapBnd"], 16) or fields["NoNewPrivs"].strip() != "1":
        raise PodError(f"the server has capabilities or may gain privileges: {fields}")
    say("-- the server: no capability (CapEff, CapBnd 0), NoNewPrivs 1")
    written = written_files(Path(f"/proc/{server.pid}/root"), writable_mounts(pod), keep)
    say(f"-- written in the emptyDir volumes: {', '.join(map(str, written)) or 'nothing'}")
    stop(pod, server, host_ports)


def scrape(pod: Pod, host_ports: dict[int, int]) -> None:
    """The metrics where the pod's Prometheus annotations say: they must count the demo's plan."""
    port = int(pod.annotations["prometheus.io/port"])
    if port not in host_ports:
        raise PodError(f"prometheus.io/port {port} is not a port the service listens on")
    path = pod.annotations.get("prometheus.io/path", "/metrics")
    status, text = http(f"http://127.0.0.1:{host_ports[port]}{path}")
    plans = re.search(rb'^kappa_plans_total\{status="ok"\} ([0-9.]+)$', text, flags=re.MULTILINE)
    if status != 200 or not plans or float(plans.group(1)) < 1:
        raise PodError(f"metrics on port {port}{path}: {status}, no plan counted")
    say(
        f"-- metrics (prometheus.io/port {port}, {path}): 200, kappa_plans_total ok {plans.group(1).decode()}"
    )


def written_files(root: Path, mounts: list[tuple[int, str]], keep: list[Path]) -> list[Path]:
    """The files and folders in the emptyDir volumes as the server sees them (``root``: its
    ``/proc/PID/root``), less the paths bound back for the replay."""
    found = []
    for _, path in mounts:
        for entry in (root / path.lstrip("/")).rglob("*"):
            seen = Path("/") / entry.relative_to(root)
            if not any(seen.is_relative_to(k) or k.is_relative_to(seen) for k in keep):
                found.append(seen)
    return sorted(found)


def stop(pod: Pod, server: subprocess.Popen[bytes], host_ports: dict[int, int]) -> None:
    """The kubelet's stop: the preStop hook (the pod must stay ready meanwhile), then SIGTERM."""
    t0 = time.monotonic()
    hook = pod.container.get("lifecycle", {}).get("preStop")
    if hook:
        if "exec" not in hook:
            raise PodError(f"only exec preStop hooks are replayed: {hook}")
        ready_url, timeout = probe_url(pod, pod.container["readinessProbe"], host_ports)
        with subprocess.Popen(hook["exec"]["command"]) as running:
            while running.poll() is None:
                if status_of(ready_url, timeout) != 200:
                    raise PodError("the service stopped being ready during the preStop hook")
                time.sleep(0.5)
        if running.returncode != 0:
            raise PodError(f"the preStop hook exited with {running.returncode}")
    hook_s = time.monotonic() - t0
    server.send_signal(signal.SIGTERM)
    left = pod.grace_s - hook_s
    try:
        code = server.wait(timeout=left)
    except subprocess.TimeoutExpired:
        raise PodError(f"still running {left:.1f} s after SIGTERM: the kubelet would SIGKILL it") from None
    took = time.monotonic() - t0 - hook_s
    if code != 0:
        raise PodError(f"the service exited with {code} after SIGTERM")
    say(
        f"-- stop: preStop {hook_s:.1f} s, then SIGTERM: exit 0 after {took:.1f} s "
        f"(terminationGracePeriodSeconds {pod.grace_s:g} s)"
    )


def inside(workdir: str, mounts: list[str], keep: list[str], cmd: list[str]) -> NoReturn:
    """In the new mount namespace (``unshare --mount``): the root read-only, a tmpfs per emptyDir
    (``SIZE:PATH``), the ``keep`` paths they hide bound back read-only, then ``cmd`` run in ``workdir``
    without capabilities or new privileges (``setpriv``, this process's pid)."""

    def mount(*args: str) -> None:
        subprocess.run(["mount", *args], check=True)

    mount("--make-rprivate", "/")
    mount("-o", "remount,bind,ro", "/")
    held = {path: os.open(path, os.O_RDONLY | os.O_DIRECTORY) for path in [*keep, workdir]}
    for item in mounts:
        size, path = item.split(":", 1)
        mount("-t", "tmpfs", "-o", f"size={size},mode=1777,nosuid,nodev", "emptydir", path)
    for path in keep:
        os.makedirs(path, exist_ok=True)  # in the tmpfs that hid it
        # no canonicalising: the fd's path now names the empty folder in the tmpfs that hid it
        mount("--no-canonicalize", "--bind", f"/proc/{os.getpid()}/fd/{held[path]}", path)
        mount("-o", "remount,bind,ro", path)
    os.chdir(workdir)
    for fd in held.values():
        os.close(fd)
    setpriv = shutil.which("setpriv") or "setpriv"
    caps = ["--no-new-privs", "--inh-caps=-all", "--ambient-caps=-all", "--bounding-set=-all"]
    os.execv(setpriv, [setpriv, *caps, "--", *cmd])


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--inside"]:  # the server's side of the replay (see replay)
        inner = argparse.ArgumentParser()
        inner.add_argument("--inside", required=True)
        inner.add_argument("--mount", action="append", default=[])
        inner.add_argument("--keep", action="append", default=[])
        inner.add_argument("cmd", nargs="+")
        args = inner.parse_args(argv)
        inside(args.inside, args.mount, args.keep, args.cmd)
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("rendered", type=Path, help="the rendered manifests (kubectl kustomize deploy/k8s)")
    args = parser.parse_args(argv)
    if os.geteuid() != 0 or not sys.platform.startswith("linux"):
        say("needs Linux and root (a mount namespace of its own)")
        return 1
    try:
        with tempfile.TemporaryDirectory(prefix="kappa-pod-") as scratch:
            replay(args.rendered, Path(scratch))
    except ReplayError as exc:  # PodError, or the demo's plan (dockerfile_replay.plan_demo)
        say(f"FAILED: {exc}")
        return 1
    say("the pod works as deployed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
