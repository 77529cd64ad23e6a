"""Closed loop on real roads: ``python bench/commonroad.py`` drives every CommonRoad scenario and prints
a markdown table (asserts nothing; also written to ``bench/results/commonroad.md``).

Scenarios: the planning requests ``tests/data/commonroad/*.json`` (converted from the CommonRoad
benchmark by the shared reference converter; ``index.json`` beside them gives each goal) — with
``--road``, the same requests with the whole road beyond the lane, ``tests/data/commonroad-road/*.json``
(same goals), so that the plans may borrow it —, or with ``--xml DIR`` the CommonRoad XML files converted
by :mod:`planner_tools.commonroad` (needs the ``commonroad`` extra; their ``road`` kept only with
``--road``). Each is driven by :func:`planner_tools.sim.simulate` with a replan every 0.1 s until the goal, a
collision or ``--duration`` simulated seconds (default 35 s).

Goal: the scenario's goal region as an arc length ``s_min`` on the reference; a scenario whose goal is a
time window only (CommonRoad's "survive until …") gets ``min(reference end − one vehicle length,
s_ego + target_speed · duration · 0.6)``, a distance it can reach in the time allowed.

Vehicle (``--vehicle``): the requests' own (``request``: the point model for the shared requests, the
car of CommonRoad's vehicle type 2 for XML), that car (``car``: wheelbase, rear axle, steering limits of
the BMW 320i), or the same footprint as the point model (``point``). ``--feasibility`` (the extra
``commonroad``) judges every driven transition, every 0.1 s, with commonroad-drivability-checker's
kinematic single-track feasibility check of vehicle type 2 (its position and orientation tolerances,
its steering limits), as a CommonRoad solution of the driven motion would be judged.

Columns: goal reached, collisions (sub-steps whose footprint hits an obstacle), min clearance of the
footprint to any obstacle [m], the farthest a footprint corner got outside the lane [m] (≤ 0: inside)
and with ``--road`` outside the road, the cycles that borrowed the road (``diagnostics.decision``),
median / max wall time of one ``plan`` call [ms], replan cycles, the plans' status counts (ok / stopped /
fallback / error), how the run ended, the distance driven, and with ``--feasibility`` the feasible
transitions.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

# bench/ itself must not be on the path: this file would shadow the commonroad package
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner.frenet import to_frenet  # noqa: E402
from planner.reference import build_reference  # noqa: E402
from planner_tools.commonroad import (  # noqa: E402 (after the path fix)
    Conversion,
    car_vehicle,
    driven_states,
    feasible_transitions,
    load,
    point_vehicle,
)
from planner_tools.io import problem_from_json  # noqa: E402
from planner_tools.sim import Goal, SimResult, simulate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
REQUESTS = ROOT / "tests" / "data" / "commonroad"
ROAD_REQUESTS = ROOT / "tests" / "data" / "commonroad-road"
RESULTS = ROOT / "bench" / "results"
#: share of the time allowed that a time-only goal's distance is planned for
SURVIVAL_SHARE = 0.6


#: the step [s] at which driven transitions are judged (the replan period)
FEASIBILITY_DT = 0.1


@dataclass(frozen=True)
class Row:
    name: str
    result: SimResult
    goal_s: float
    wall_s: float
    feasible: list[bool] | None = None


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


def run_one(
    path: Path, duration: float, vehicle: str = "request", feasibility: bool = False, road: bool = False
) -> Row:
    conv = load(path)
    if path.parent == ROAD_REQUESTS and (REQUESTS / path.name).exists():  # the goals of the same scenes
        conv = replace(conv, goal=load(REQUESTS / path.name).goal)
    if not road and "road" in conv.request:
        conv = replace(conv, request={k: v for k, v in conv.request.items() if k != "road"})
    if vehicle != "request":
        made = car_vehicle if vehicle == "car" else point_vehicle
        conv = replace(conv, request={**conv.request, "vehicle": made(conv.request["vehicle"])})
    problem = problem_from_json(conv.request)
    goal_s = scenario_goal(conv, duration)
    t0 = time.perf_counter()
    result = simulate(problem, duration=duration, goal=Goal(s_min=goal_s))
    wall = time.perf_counter() - t0
    feasible = None
    if feasibility:
        feasible = feasible_transitions(driven_states(result.motion, FEASIBILITY_DT), FEASIBILITY_DT)
    return Row(conv.name, result, goal_s, wall, feasible)


def _fmt(value: float | None, digits: int = 2) -> str:
    return "—" if value is None else f"{value:.{digits}f}"


def _share(feasible: list[bool]) -> str:
    return f"{sum(feasible)} / {len(feasible)}" if feasible else "—"


def _percent(feasible: list[bool]) -> str:
    return f"{100.0 * sum(feasible) / max(len(feasible), 1):.1f} %"


def borrowed(result: SimResult) -> int:
    """Cycles whose plan borrowed the road beyond the lane."""
    return sum(step.decision is not None and step.decision.borrows for step in result.steps)


def table(rows: list[Row], road: bool = False) -> str:
    judged = any(r.feasible is not None for r in rows)
    head = "| scenario | goal reached | collisions | min clearance [m] | lane departure [m] |"
    head += " road departure [m] | borrowed |" if road else ""
    head += (
        " plan median [ms] | plan max [ms] | steps | ok / stopped / fallback / error | end "
        "| driven [m] / goal [m] |"
    )
    head += " feasible transitions |" if judged else ""
    lines = [head, "|" + "---|" * (11 + 2 * road + judged)]
    for r in rows:
        m = r.result.metrics
        c = m.status_counts
        start = float(r.result.motion.s[0])
        line = (
            f"| {r.name} | {'yes' if m.goal_reached else 'no'} | {m.collisions} | {_fmt(m.min_clearance)} "
            f"| {m.max_lane_departure:.2f} |"
        )
        if road:
            line += f" {m.max_road_departure:.2f} | {borrowed(r.result)} |"
        line += (
            f" {m.planning_ms['median']:.0f} | {m.planning_ms['max']:.0f} "
            f"| {m.steps} | {c['ok']} / {c['stopped']} / {c['fallback']} / {c['error']} | {m.termination} "
            f"| {m.final_s - start:.0f} / {r.goal_s - start:.0f} |"
        )
        lines.append(line + (f" {_share(r.feasible or [])} |" if judged else ""))
    reached = sum(r.result.metrics.goal_reached for r in rows)
    hits = sum(r.result.metrics.collisions > 0 for r in rows)
    departed = sum(r.result.metrics.max_lane_departure > 1e-3 for r in rows)
    lines.append("")
    summary = f"{reached}/{len(rows)} goals reached, {hits} runs with a collision, {departed} off the lane"
    if road:
        off_road = sum(r.result.metrics.max_road_departure > 1e-3 for r in rows)
        summary += f", {off_road} off the road"
    summary += "."
    if judged:
        every = [f for r in rows for f in (r.feasible or [])]
        clean = [f for r in rows if r.result.metrics.collisions == 0 for f in (r.feasible or [])]
        summary += (
            f" Feasible transitions: {_share(every)} ({_percent(every)}); on the runs without a collision "
            f"{_share(clean)} ({_percent(clean)})."
        )
    lines.append(summary)
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=35.0, help="simulated seconds per scenario at most")
    parser.add_argument(
        "--xml", type=Path, default=None, help="convert the CommonRoad XML files in DIR instead"
    )
    parser.add_argument("--only", nargs="*", default=None, help="scenario names (file stems) to run")
    parser.add_argument("--out", type=Path, default=None, help="markdown file (default bench/results/…)")
    parser.add_argument(
        "--vehicle", choices=("request", "car", "point"), default="request", help="see the module docstring"
    )
    parser.add_argument(
        "--feasibility", action="store_true", help="judge the driven transitions with CommonRoad's checker"
    )
    parser.add_argument(
        "--road", action="store_true", help="with the whole road beyond the lane (see the module docstring)"
    )
    args = parser.parse_args(argv)

    suffix = "_road" if args.road else ""
    if args.xml is None:
        folder = ROAD_REQUESTS if args.road else REQUESTS
        paths = sorted(p for p in folder.glob("*.json") if p.name != "index.json")
        source = f"requests in {folder.relative_to(ROOT)}"
        out = args.out or RESULTS / f"commonroad{suffix}.md"
    else:
        paths = sorted(args.xml.glob("*.xml"))
        source = f"CommonRoad XML in {args.xml}, converted by planner_tools.commonroad"
        out = args.out or RESULTS / f"commonroad_xml{suffix}.md"
    if args.only:
        paths = [p for p in paths if p.stem in set(args.only)]
    rows: list[Row] = []
    t0 = time.perf_counter()
    for path in paths:
        row = run_one(path, args.duration, args.vehicle, args.feasibility, args.road)
        m = row.result.metrics
        print(
            f"{row.name}: {m.termination} after {m.sim_time:.1f} s sim, {m.steps} steps, "
            f"{row.wall_s:.1f} s wall",
            file=sys.stderr,
        )
        rows.append(row)
    total = time.perf_counter() - t0
    text = table(rows, args.road)
    cpu = os.cpu_count()
    header = (
        f"# Closed loop on CommonRoad scenarios\n\n"
        f"`python bench/commonroad.py{' '.join(['', *(argv if argv is not None else sys.argv[1:])])}`: "
        f"{source}; vehicle: {args.vehicle}; "
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
