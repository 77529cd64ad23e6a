"""Does throughput scale with replicas? ``python bench/replicas.py`` prints figures (asserts nothing).

Runs ``bench/load.py`` with servers of its own, loopback only, in several shapes, interleaved (one run of
each shape per round, ``--rounds`` rounds), and prints each run's figures and a table of medians. A shape
is ``REPLICASxPROCESSES``: that many separate ``python -m app`` servers (one HTTP worker each, as a pod of
deploy/k8s), each with ``KAPPA_PLAN_PROCESSES=PROCESSES`` and pinned to as many CPUs of its own — a pod
whose CPU limit is its plan pool, as deploy/k8s sizes them. The default shapes, on a 2-core machine:

* ``1x1`` — one replica on one CPU: the unit a cluster adds;
* ``2x1`` — two such replicas, the clients spread over them as a Service spreads connections: scaling
  out, with twice the CPUs;
* ``1x2`` — one replica with 2 plan processes on 2 CPUs: the same CPUs as ``2x1`` in one pod.

``2x1`` against ``1x1`` is the scaling (ideal: 2×; a cluster gives each replica CPUs of its own, this
machine has only two, shared with the load generator). ``2x1`` against ``1x2`` says whether splitting
the same CPUs into replicas costs throughput (each replica brings its own worker and supervisor). The
load generator and other jobs on the machine share the CPUs: the load average is printed per run, and
the exact command of each shape, to rerun at a quiet time. So are the CPUs the servers got (their CPU
time over the wall time): a saturated shape that got fewer CPUs than it may use lost them to other jobs,
and its plans per second say more about the machine than about the shape; its plans per CPU-second
(plans per second over the CPUs it got) still compare the shapes' efficiency.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import re
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import load  # bench/load.py: the same servers, clients and figures

ROOT = Path(__file__).resolve().parents[1]
SHAPE = re.compile(r"(\d+)x(\d+)")


def shape_options(shape: str, args: argparse.Namespace) -> list[str]:
    """The options of ``bench/load.py`` for ``shape`` (``REPLICASxPROCESSES``)."""
    match = SHAPE.fullmatch(shape)
    if not match:
        sys.exit(f"a shape is REPLICASxPROCESSES, e.g. 2x1: {shape!r}")
    replicas, processes = match.groups()
    return [
        *("--replicas", replicas, "--plan-processes", processes, "--cpus-per-replica", processes),
        *("--clients", str(args.clients), "--duration", f"{args.duration:g}"),
    ]


def commit() -> str:
    """The checked-out commit (and whether the tree differs from it), or '?' outside git."""
    try:
        head = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(ROOT), "diff", "--quiet", "HEAD"], check=False).returncode
    except (OSError, subprocess.CalledProcessError):
        return "?"
    return head + (" (with changes)" if dirty else "")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--shapes", default="1x1,2x1,1x2", help="comma-separated REPLICASxPROCESSES")
    parser.add_argument("--rounds", type=int, default=3, help="runs of each shape, interleaved")
    parser.add_argument("--clients", type=int, default=200, help="concurrent clients, over all replicas")
    parser.add_argument("--duration", type=float, default=10.0, help="seconds of load per run")
    args = parser.parse_args(argv)
    if not 1 <= args.rounds <= 20:
        parser.error("1 ≤ rounds ≤ 20")
    shapes = [s.strip() for s in args.shapes.split(",") if s.strip()]
    cpus = len(os.sched_getaffinity(0))
    commands = {shape: shape_options(shape, args) for shape in shapes}

    print(f"# {shlex.join([Path(sys.executable).name, *sys.argv])}")
    print(
        f"# {datetime.datetime.now().astimezone():%Y-%m-%d %H:%M %Z}, commit {commit()}, {cpus} CPUs, "
        f"Python {platform.python_version()}, load average {' '.join(f'{v:.2f}' for v in os.getloadavg())}"
    )
    for shape, options in commands.items():
        print(f"# {shape}: python bench/load.py {shlex.join(options)}")

    results: dict[str, list[load.Result]] = {shape: [] for shape in shapes}
    for round_ in range(1, args.rounds + 1):
        for shape in shapes:
            options = load.parser()
            run_args = options.parse_args(commands[shape])
            load.check_bounds(options, run_args)
            print(f"\n## round {round_}, {shape}")
            with (
                tempfile.TemporaryDirectory(prefix="kappa-replicas-") as logs,
                load.own_servers(
                    run_args.replicas,
                    run_args.workers,
                    run_args.plan_processes,
                    run_args.cpus_per_replica,
                    Path(logs),
                ) as servers,
            ):
                result = load.run([url for url, _ in servers], run_args, [pid for _, pid in servers])
            load.report(result, run_args)
            results[shape].append(result)
            sys.stdout.flush()

    columns = ["shape", "plans/s, each run", "median plans/s", "latency p50 / p99 [ms] (medians)"]
    columns += ["errors", "non-200", "CPUs the servers got, each run", "plans per CPU-second (median)"]
    columns += ["load average (1 min) before each run"]
    print("\n| " + " | ".join(columns) + " |")
    print("|" + " --- |" * len(columns))
    medians = {}
    for shape, runs in results.items():
        rates = [r.plans_per_s for r in runs]
        medians[shape] = float(np.median(rates))
        p50 = np.median([r.latency_ms[0] for r in runs])
        p99 = np.median([r.latency_ms[2] for r in runs])
        errors = sum(sum(r.errors.values()) for r in runs)
        others = sum(sum(r.others.values()) for r in runs)
        loads = ", ".join(f"{r.load_before[0]:.1f}" for r in runs)
        got = ", ".join(f"{r.server_cpus:.2f}" if r.server_cpus is not None else "?" for r in runs)
        per_cpu = np.median([r.plans_per_s / r.server_cpus for r in runs if r.server_cpus])
        each = ", ".join(f"{x:.1f}" for x in rates)
        cells = [shape, each, f"{medians[shape]:.1f}", f"{p50:.0f} / {p99:.0f}", errors, others, got]
        cells += [f"{per_cpu:.1f}", loads]
        print("| " + " | ".join(map(str, cells)) + " |")
    for a, b in (("2x1", "1x1"), ("2x1", "1x2")):
        if a in medians and b in medians and medians[b] > 0:
            print(f"\n{a} / {b}: {medians[a] / medians[b]:.2f}× the plans per second (medians)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
