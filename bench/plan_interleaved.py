"""Plan latency of two checkouts, interleaved in one run: ``python bench/plan_interleaved.py OTHER``.

Each checkout (this one and ``OTHER``, e.g. a ``git worktree`` of the base commit) plans the scenes of its
own ``bench/plan.py`` (``scenes()``) in a process of its own; the two processes take turns, ``--plans``
plans of one scene each, the order flipped every round, so that both see the same load on a shared
machine. Prints per scene the median and p99 wall time of a plan [ms] of each and the ratio of the
medians (asserts nothing).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def worker(root: Path) -> None:
    """Plan the scenes of ``root``'s bench/plan.py on request (``scene plans`` per line on stdin)."""
    sys.path[:0] = [str(root), str(root / "bench")]
    import plan as bench_plan  # that checkout's bench/plan.py

    from planner.pipeline import plan

    scenes = bench_plan.scenes()
    names = list(scenes)
    for problem in scenes.values():  # the first plan also builds the speed problem
        plan(problem)
    print(json.dumps(names), flush=True)
    for line in sys.stdin:
        k, n = map(int, line.split())
        problem = scenes[names[k]]
        out = []
        for _ in range(n):
            t0 = time.perf_counter()
            plan(problem)
            out.append(1e3 * (time.perf_counter() - t0))
        print(json.dumps(out), flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("other", type=Path, help="the other checkout (its root)")
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("--plans", type=int, default=10, help="plans of one scene per turn")
    parser.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker is not None:
        worker(args.worker)
        return 0
    trees = {"other": args.other.resolve(), "this": ROOT}
    procs = {
        name: subprocess.Popen(
            [sys.executable, __file__, str(root), "--worker", str(root)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        for name, root in trees.items()
    }
    names = {name: json.loads(p.stdout.readline()) for name, p in procs.items() if p.stdout}
    scenes = [s for s in names["this"] if s in names["other"]]
    times: dict[str, dict[str, list[float]]] = {name: {s: [] for s in scenes} for name in trees}
    for r in range(args.rounds):
        for s in scenes:
            for name in trees if r % 2 == 0 else reversed(list(trees)):
                p = procs[name]
                assert p.stdin is not None and p.stdout is not None
                p.stdin.write(f"{names[name].index(s)} {args.plans}\n")
                p.stdin.flush()
                times[name][s] += json.loads(p.stdout.readline())
    for p in procs.values():
        if p.stdin:
            p.stdin.close()
        p.wait()
    print(
        f"{args.rounds} rounds × {args.plans} plans per scene and checkout, taking turns; this: {ROOT}, "
        f"other: {trees['other']}"
    )
    for s in scenes:
        a, b = np.array(times["this"][s]), np.array(times["other"][s])
        print(
            f"{s:48s} median this {np.median(a):6.2f} ms, other {np.median(b):6.2f} ms, ratio "
            f"{np.median(a) / np.median(b):.3f}; p99 this {np.percentile(a, 99):6.1f}, other "
            f"{np.percentile(b, 99):6.1f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
