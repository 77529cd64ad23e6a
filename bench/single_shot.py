"""Single-shot answers to the shared CommonRoad requests: ``python bench/single_shot.py`` plans the first
request of each scene (``tests/data/commonroad/*.json``, the scene at its initial time) through the app
in-process and prints, per scene, the status, the speed profile, the vehicle from behind named in the
diagnostics and what the answer breaks by the independent checks of ``tests/regression/checks.py``
(every status held to the vehicle's limits; ``ok`` and ``stopped`` to every check; a fallback that brakes
to braking, one that does not to every check but the hits of the vehicles behind; a fallback that
brakes at full deceleration from the start is excused the limits its start state cannot keep) and,
apart, the vehicle's limits it breaks without that excuse. Asserts nothing.

``--vehicle car`` plans CommonRoad's vehicle type 2 as a car instead of the requests' point model,
``--speed-limit V`` sets ``options.speed_limit`` (at least the target), as ``bench/commonroad.py`` does.
``--closed-loop`` drives every scene as ``bench/commonroad.py`` does and checks every cycle's answer
against the vehicle's limits (:func:`tests.regression.checks.limit_problems`, no excuse): how many
answers of each status break one, and which limits.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
from collections import Counter
from dataclasses import replace
from pathlib import Path
from typing import Any

# bench/ itself must not be on the path: bench/commonroad.py would shadow the commonroad package
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

REQUESTS = ROOT / "tests" / "data" / "commonroad"


def request_of(path: Path, vehicle: str, speed_limit: float | None) -> dict[str, Any]:
    """The scene's request, its vehicle made the car (``vehicle == "car"``) and its speed limit set."""
    from planner_tools.commonroad import car_vehicle

    request: dict[str, Any] = json.loads(path.read_text())
    if vehicle == "car":
        request["vehicle"] = car_vehicle(request["vehicle"])
    if speed_limit is not None:
        options = request.setdefault("options", {})
        options["speed_limit"] = max(speed_limit, float(options.get("target_speed") or 0.0))
    request.setdefault("options", {})["time_budget_ms"] = 60_000.0  # a loaded machine changes no answer
    return request


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--vehicle", choices=("request", "car"), default="request")
    parser.add_argument("--speed-limit", type=float, default=None, metavar="V")
    parser.add_argument("--closed-loop", action="store_true", help="check every cycle of the closed loops")
    args = parser.parse_args(argv)
    if args.closed_loop:
        return closed_loop(args.vehicle, args.speed_limit)

    from fastapi.testclient import TestClient

    from app.conversions import to_problem
    from app.main import create_app
    from app.models.planning import PlanningRequest
    from app.settings import Settings
    from tests.regression.checks import STATUSES, limit_problems, plan_problems, trajectory_of

    paths = sorted(p for p in REQUESTS.glob("*.json") if p.name != "index.json")
    print("| scene | status | profile | follower | breaks | vehicle limits |\n|---|---|---|---|---|---|")
    broken = beyond = 0
    with TestClient(create_app(Settings(log_level="warning", plan_processes=1))) as client:
        for path in paths:
            request = request_of(path, args.vehicle, args.speed_limit)
            answer = client.post("/v1/plan", json=request).json()
            problems = plan_problems(request, answer, STATUSES)
            problem = to_problem(PlanningRequest.model_validate(request))
            limits = limit_problems(problem, trajectory_of(answer))
            broken += bool(problems)
            beyond += bool(limits)
            follower = answer["diagnostics"].get("follower")
            named = "—" if follower is None else f"{follower['obstacle_id']} ({follower['reason']})"
            print(
                f"| {path.stem} | {answer['status']} | {answer['diagnostics']['speed']['profile']} | {named} "
                f"| {'; '.join(problems)[:160] or '—'} | {'; '.join(limits)[:120] or '—'} |"
            )
    print(
        f"\n{broken} of {len(paths)} answers break a check, {beyond} a vehicle limit (excused or not); "
        f"vehicle: {args.vehicle}, speed limit: {args.speed_limit}."
    )
    return 0


def closed_loop(vehicle: str, speed_limit: float | None) -> int:
    """Every cycle's answer of every scene's closed loop against the vehicle's limits."""
    from planner_tools.commonroad import load
    from planner_tools.io import problem_from_json
    from planner_tools.sim import Goal, simulate
    from tests.regression.checks import limit_problems

    spec = importlib.util.spec_from_file_location("bench_commonroad", ROOT / "bench" / "commonroad.py")
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    sys.modules["bench_commonroad"] = bench
    spec.loader.exec_module(bench)  # its scenario_goal: the same goals as the closed-loop bench

    cycles: Counter[str] = Counter()
    beyond: Counter[str] = Counter()
    kinds: Counter[str] = Counter()
    for path in sorted(p for p in REQUESTS.glob("*.json") if p.name != "index.json"):
        request = request_of(path, vehicle, speed_limit)
        del request["options"]["time_budget_ms"]
        problem = problem_from_json(request)
        goal = Goal(s_min=bench.scenario_goal(replace(load(path), request=request), 35.0))
        result = simulate(problem, duration=35.0, goal=goal)
        broken = 0
        for step in result.steps:
            if step.trajectory is None:
                continue
            cycles[step.status] += 1
            problems = limit_problems(problem, step.trajectory)
            broken += bool(problems)
            beyond[step.status] += bool(problems)
            kinds.update(" ".join(p.split(" ")[:2]) for p in problems)
        print(f"{path.stem}: {len(result.steps)} cycles, {broken} beyond a vehicle limit", file=sys.stderr)
    per_status = ", ".join(f"{s} {beyond[s]} / {cycles[s]}" for s in sorted(cycles))
    print(f"{sum(beyond.values())} of {sum(cycles.values())} answers beyond a vehicle limit ({per_status})")
    print(f"limits broken: {dict(kinds)}; vehicle: {vehicle}, speed limit: {speed_limit}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
