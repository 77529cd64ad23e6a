"""Plans within a time budget: how far past ``options.time_budget_ms`` the answers come (prints figures,
asserts nothing).

A plan checks its budget after each stage and keeps a share of it for the fallback an overrun leads to;
inside the lateral stage it skips the re-solves that only improve a path once the budget no longer leaves
what the solve before took. This replays hard cycles with a budget set and prints, per budget, the wall
time of each plan in this process (median, p90, max), how many came past the budget and past 1.1 × it,
and the answers' statuses::

    python bench/budget.py --record DIR              # the closed loops' requests (needs the commonroad extra)
    python bench/budget.py --replay DIR --budget 100 200

``--record`` drives the closed loops of ``--xml`` scenes (default: the XML conversions of HRV_Pula-27_3,
twelve lateral QPs a plan in its borrowed road, and DEU_Lohmar-26, with the car, as ``bench/commonroad.py
--xml`` does) and writes every request a plan was asked. ``--replay`` plans each request once after three
warm-up plans (the first plans of a process build the speed problems), with each budget in turn. It
works on any checkout of the planner (it needs ``planner_tools.io`` and ``planner.pipeline`` only), so a
worktree of the previous commit can replay the same DIR, the two runs interleaved.
"""

from __future__ import annotations

import argparse
import collections
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
# bench/ itself must not be on the path (bench/commonroad.py would shadow the commonroad package)
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(ROOT))

from planner.pipeline import plan  # noqa: E402 (after the path fix)
from planner_tools.io import problem_from_json, problem_to_json  # noqa: E402

#: the scenes recorded by default: hard cycles for the lateral stage
DEFAULT_SCENES = (
    ROOT / "tests" / "data" / "commonroad" / "HRV_Pula-27_3_T-1.xml.gz",
    ROOT / "tests" / "data" / "commonroad" / "DEU_Lohmar-26_1_T-1.xml.gz",
)


def record(scenes: list[Path], out: Path) -> int:
    """Drive each scene's closed loop (the car) and write every request it asked to ``out``; how many."""
    import planner_tools.sim as sim
    from planner_tools.evaluate import Settings, run_scene

    out.mkdir(parents=True, exist_ok=True)
    asked: list[Any] = []
    planned = sim.plan

    def recorded(problem: Any, *args: Any, **kwargs: Any) -> Any:
        asked.append(problem)
        return planned(problem, *args, **kwargs)

    sim.plan = recorded
    try:
        for scene in scenes:
            start = len(asked)
            run_scene(scene, Settings(vehicle="car"))
            for k, problem in enumerate(asked[start:]):
                body = problem_to_json(problem)
                (out / f"{scene.name.split('.')[0]}_{k:04d}.json").write_text(json.dumps(body))
    finally:
        sim.plan = planned
    return len(asked)


def replay(folder: Path, budgets: list[float]) -> str:
    """Plan every request in ``folder`` with each budget [ms]; the figures as text."""
    bodies = [json.loads(p.read_text()) for p in sorted(folder.glob("*.json"))]
    if not bodies:
        raise SystemExit(f"no requests in {folder}")
    lines = [f"{len(bodies)} requests from {folder}; wall time of each plan in this process [ms]"]
    for budget in budgets:
        problems = []
        for body in bodies:
            options = {**body.get("options", {}), "time_budget_ms": budget}
            problems.append(problem_from_json({**body, "options": options}))
        for problem in problems[:3]:
            plan(problem)
        times: list[float] = []
        statuses: collections.Counter[str] = collections.Counter()
        for problem in problems:
            t0 = time.perf_counter()
            result = plan(problem)
            times.append(1e3 * (time.perf_counter() - t0))
            statuses[result.status] += 1
        ms = np.asarray(times)
        lines.append(
            f"budget {budget:g} ms: median {np.median(ms):.1f} p90 {np.percentile(ms, 90):.1f} "
            f"max {ms.max():.1f}; over the budget {int(np.sum(ms > budget))}, over 1.1 × it "
            f"{int(np.sum(ms > 1.1 * budget))}; statuses {dict(sorted(statuses.items()))}"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--record", type=Path, help="write the closed loops' requests here")
    parser.add_argument("--xml", type=Path, nargs="*", help="scenes to record (default: see the docstring)")
    parser.add_argument("--replay", type=Path, help="plan the requests in this folder")
    parser.add_argument("--budget", type=float, nargs="+", default=[100.0], help="budgets [ms]")
    args = parser.parse_args(argv)
    if args.record is None and args.replay is None:
        parser.error("give --record DIR, --replay DIR or both")
    if args.record is not None:
        count = record(list(args.xml or DEFAULT_SCENES), args.record)
        print(f"{count} requests written to {args.record}")
    if args.replay is not None:
        print(replay(args.replay, args.budget))


if __name__ == "__main__":
    main()
