"""Closed loop on real roads: ``python bench/commonroad.py`` drives every CommonRoad scenario and prints
a markdown table (asserts nothing; also written to ``bench/results/commonroad.md``).

Scenarios: the planning requests ``tests/data/commonroad/*.json`` (converted from the CommonRoad
benchmark by the shared reference converter; ``index.json`` beside them gives each goal), or with
``--xml DIR`` the CommonRoad XML files converted by :mod:`planner_tools.commonroad` (needs the ``commonroad``
extra). Each is driven by :func:`planner_tools.sim.simulate` with a replan every 0.1 s until the goal, a
collision or ``--duration`` simulated seconds (default 35 s).

Goal: the scenario's goal region as an arc length ``s_min`` on the reference; a scenario whose goal is a
time window only (CommonRoad's "survive until …") gets ``min(reference end − one vehicle length,
s_ego + target_speed · duration · 0.6)``, a distance it can reach in the time allowed.

Columns: goal reached, collisions (sub-steps whose footprint hits an obstacle), min clearance of the
footprint to any obstacle [m], median / max wall time of one ``plan`` call [ms], replan cycles, the
plans' status counts (ok / stopped / fallback / error), how the run ended, and the distance driven.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

# bench/ itself must not be on the path: this file would shadow the commonroad package
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner.frenet import to_frenet  # noqa: E402
from planner.reference import build_reference  # noqa: E402
from planner_tools.commonroad import Conversion, load  # noqa: E402 (after the path fix)
from planner_tools.io import problem_from_json  # noqa: E402
from planner_tools.sim import Goal, SimResult, simulate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
REQUESTS = ROOT / "tests" / "data" / "commonroad"
RESULTS = ROOT / "bench" / "results"
#: share of the time allowed that a time-only goal's distance is planned for
SURVIVAL_SHARE = 0.6


@dataclass(frozen=True)
class Row:
    name: str
    result: SimResult
    goal_s: float
    wall_s: float


def scenario_goal(conv: Conversion, duration: float) -> float:
    """The goal's arc length [m] on the reference (see the module docstring)."""
    problem = problem_from_json(conv.request)
    ref = build_reference(problem.reference_line)
    end = ref.length - problem.vehicle.length
    s_min = conv.goal.get("s_min")
    if s_min is not None:
        return float(min(s_min, end))
    s_ego = float(to_frenet(ref, [[problem.ego.x, problem.ego.y]]).s[0])
    speed = problem.options.target_speed or problem.vehicle.max_speed
    return float(min(end, s_ego + speed * duration * SURVIVAL_SHARE))


def run_one(path: Path, duration: float) -> Row:
    conv = load(path)
    problem = problem_from_json(conv.request)
    goal_s = scenario_goal(conv, duration)
    t0 = time.perf_counter()
    result = simulate(problem, duration=duration, goal=Goal(s_min=goal_s))
    return Row(conv.name, result, goal_s, time.perf_counter() - t0)


def _fmt(value: float | None, digits: int = 2) -> str:
    return "—" if value is None else f"{value:.{digits}f}"


def table(rows: list[Row]) -> str:
    head = (
        "| scenario | goal reached | collisions | min clearance [m] | plan median [ms] | plan max [ms] "
        "| steps | ok / stopped / fallback / error | end | driven [m] / goal [m] |"
    )
    lines = [head, "|" + "---|" * 10]
    for r in rows:
        m = r.result.metrics
        c = m.status_counts
        start = float(r.result.motion.s[0])
        lines.append(
            f"| {r.name} | {'yes' if m.goal_reached else 'no'} | {m.collisions} | {_fmt(m.min_clearance)} "
            f"| {m.planning_ms['median']:.0f} | {m.planning_ms['max']:.0f} | {m.steps} "
            f"| {c['ok']} / {c['stopped']} / {c['fallback']} / {c['error']} | {m.termination} "
            f"| {m.final_s - start:.0f} / {r.goal_s - start:.0f} |"
        )
    reached = sum(r.result.metrics.goal_reached for r in rows)
    hits = sum(r.result.metrics.collisions > 0 for r in rows)
    lines.append("")
    lines.append(f"{reached}/{len(rows)} goals reached, {hits} runs with a collision.")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=35.0, help="simulated seconds per scenario at most")
    parser.add_argument(
        "--xml", type=Path, default=None, help="convert the CommonRoad XML files in DIR instead"
    )
    parser.add_argument("--only", nargs="*", default=None, help="scenario names (file stems) to run")
    parser.add_argument("--out", type=Path, default=None, help="markdown file (default bench/results/…)")
    args = parser.parse_args(argv)

    if args.xml is None:
        paths = sorted(p for p in REQUESTS.glob("*.json") if p.name != "index.json")
        source = f"requests in {REQUESTS.relative_to(ROOT)}"
        out = args.out or RESULTS / "commonroad.md"
    else:
        paths = sorted(args.xml.glob("*.xml"))
        source = f"CommonRoad XML in {args.xml}, converted by planner_tools.commonroad"
        out = args.out or RESULTS / "commonroad_xml.md"
    if args.only:
        paths = [p for p in paths if p.stem in set(args.only)]
    rows: list[Row] = []
    t0 = time.perf_counter()
    for path in paths:
        row = run_one(path, args.duration)
        m = row.result.metrics
        print(
            f"{row.name}: {m.termination} after {m.sim_time:.1f} s sim, {m.steps} steps, "
            f"{row.wall_s:.1f} s wall",
            file=sys.stderr,
        )
        rows.append(row)
    total = time.perf_counter() - t0
    text = table(rows)
    cpu = os.cpu_count()
    header = (
        f"# Closed loop on CommonRoad scenarios\n\n"
        f"`python bench/commonroad.py{'' if args.xml is None else ' --xml ' + str(args.xml)}`: {source}; "
        f"replan every 0.1 s, at most {args.duration:.0f} s simulated per scenario; "
        f"{total:.0f} s wall on {cpu} cores.\n\n"
    )
    print(text)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(header + text + "\n")
    print(f"\nwrote {out} ({total:.0f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
