"""Closed-loop cycle times of two checkouts on the same requests, interleaved in one run:
``python bench/cycles_interleaved.py OTHER`` (asserts nothing).

This checkout drives the closed loops of the CommonRoad scenes as ``bench/cycles.py`` does (``--only``,
``--vehicle``, ``--xml``, ``--duration``) and keeps every cycle's request. Then each checkout (this one and
``OTHER``, e.g. a ``git worktree`` of the base commit) plans those requests in a process of its own, warmed
up as a plan process is and its heap frozen out of the cyclic GC; the two take turns, ``--chunk``
requests at a time, the order flipped every turn, ``--rounds`` times, so that both see the same load on a
shared machine. A cycle's time is its fastest plan (the spare thread's work waited for after each, as
``bench/cycles.py`` does). Prints the distribution of each (median, p90, p99, max, how many over 40 and
80 ms: issue 13's target is p99 ≤ 40 and max ≤ 80 ms), the per-cycle differences and the cycles that
moved most.

Both plan the same inputs: what is compared is the plan time, not the loops each would drive (a change
of behaviour changes the later cycles' requests; ``bench/cycles.py --compare`` says whether it did).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def worker(root: Path, requests: Path) -> None:
    """Plan the requests in ``requests`` (a JSON list) with ``root``'s planner, on request
    (``first stop`` per line on stdin: plan those, answer their wall times [ms] as one JSON line)."""
    sys.path[:0] = [str(root)]
    import gc
    import time

    from planner.pipeline import plan
    from planner.thread_solvers import thread_solvers
    from planner_tools.io import problem_from_json

    problems = [problem_from_json(r) for r in json.loads(requests.read_text())]
    try:  # warmed up as a plan process is (its speed problems built)
        from app.jobs import plan_demos
    except ImportError:
        plan(problems[0])
    else:
        plan_demos()
    gc.collect()
    gc.freeze()
    spare = getattr(thread_solvers(), "spare", None)
    print(json.dumps(len(problems)), flush=True)
    for line in sys.stdin:
        first, stop = map(int, line.split())
        out = []
        for problem in problems[first:stop]:
            start = time.perf_counter()
            plan(problem)
            out.append(1e3 * (time.perf_counter() - start))
            if spare is not None:
                spare.wait()
        print(json.dumps(out), flush=True)


def _line(name: str, fastest: np.ndarray) -> str:
    p = np.percentile(fastest, [50, 90, 99])
    return (
        f"{name:6s} median {p[0]:6.1f}  p90 {p[1]:6.1f}  p99 {p[2]:6.1f}  max {fastest.max():6.1f} ms  "
        f"over 40: {int(np.sum(fastest > 40.0)):4d}  over 80: {int(np.sum(fastest > 80.0)):3d}"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("other", type=Path, nargs="?", help="the other checkout (its root)")
    parser.add_argument("--only", nargs="*", default=None, help="scene names (file stems) to run")
    parser.add_argument("--vehicle", choices=("request", "car", "point"), default="request")
    parser.add_argument("--xml", type=Path, default=None, help="the CommonRoad XML files in DIR instead")
    parser.add_argument("--duration", type=float, default=35.0, help="simulated seconds per scene at most")
    parser.add_argument("--rounds", type=int, default=3, help="plans of every request by each checkout")
    parser.add_argument("--chunk", type=int, default=20, help="requests planned per turn")
    parser.add_argument("--moved", type=int, default=10, help="cycles that moved most to show")
    parser.add_argument("--worker", nargs=2, type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker is not None:
        worker(*args.worker)
        return 0
    if args.other is None:
        parser.error("the other checkout is required")

    sys.path.insert(0, str(ROOT / "bench"))
    import cycles

    from planner_tools.io import problem_to_json

    recorder, _ = cycles.run(args.only, args.vehicle, args.duration, keep_problems=True, xml=args.xml)
    names = [f"{c.scene} #{c.cycle}" for c in recorder.cycles]
    with tempfile.TemporaryDirectory() as tmp:
        requests = Path(tmp) / "requests.json"
        requests.write_text(json.dumps([problem_to_json(p) for p in recorder.problems]))
        roots = {"this": ROOT, "other": args.other.resolve()}
        procs: dict[str, Any] = {
            name: subprocess.Popen(
                [sys.executable, __file__, "--worker", str(root), str(requests)],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                text=True,
                cwd=root,
            )
            for name, root in roots.items()
        }
        counts = {name: json.loads(p.stdout.readline()) for name, p in procs.items()}
        n = counts["this"]
        times: dict[str, list[list[float]]] = {name: [[] for _ in range(n)] for name in procs}
        flip = False
        for _ in range(args.rounds):
            for first in range(0, n, args.chunk):
                stop = min(first + args.chunk, n)
                for name in ("other", "this") if flip else ("this", "other"):
                    procs[name].stdin.write(f"{first} {stop}\n")
                    procs[name].stdin.flush()
                    for k, t in enumerate(json.loads(procs[name].stdout.readline())):
                        times[name][first + k].append(t)
                flip = not flip
        for p in procs.values():
            p.stdin.close()
            p.wait()
    fastest = {name: np.array([min(t) for t in ts]) for name, ts in times.items()}
    print(
        f"{n} cycles ({len({c.scene for c in recorder.cycles})} scenes, vehicle {args.vehicle}), "
        f"{args.rounds} rounds of turns of {args.chunk}; each cycle's fastest plan; other = {roots['other']}"
    )
    print(_line("other", fastest["other"]))
    print(_line("this", fastest["this"]))
    diff = fastest["this"] - fastest["other"]
    print(
        f"this − other per cycle [ms]: median {np.median(diff):+.2f}, p10 {np.percentile(diff, 10):+.2f}, "
        f"p90 {np.percentile(diff, 90):+.2f}; total {fastest['other'].sum() / 1e3:.1f} → "
        f"{fastest['this'].sum() / 1e3:.1f} s"
    )
    for k in np.argsort(-np.abs(diff))[: args.moved]:
        print(f"  {names[k]:40s} {fastest['other'][k]:6.1f} → {fastest['this'][k]:6.1f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
