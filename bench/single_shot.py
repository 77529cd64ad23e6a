"""Single-shot answers to the shared CommonRoad requests: ``python bench/single_shot.py`` plans the first
request of each scene (``tests/data/commonroad/*.json``, the scene at its initial time, with the
scenario's goal and speed limit as :func:`planner_tools.evaluate.prepare` gives them to the closed loops)
through the app in-process and prints, per scene, the status, the speed profile, the vehicle from behind
named in the diagnostics and what the answer breaks by the independent checks of
``tests/regression/checks.py`` (every status held to the vehicle's limits; ``ok`` and ``stopped`` to
every check; a fallback that brakes to braking, one that does not to every check but the hits of the
vehicles behind; a fallback that brakes at full deceleration from the start is excused the limits its
start state cannot keep) and, apart, the vehicle's limits it breaks without that excuse. Asserts nothing.

``--vehicle`` as ``bench/commonroad.py``'s (default ``car``, CommonRoad's vehicle type 2).
``--xml DIR``: the CommonRoad XML files of ``DIR`` instead (``bench/swap_ego.py`` writes some).
``--closed-loop`` drives every scene as ``bench/commonroad.py`` does and checks every cycle's answer
against the vehicle's limits (:func:`tests.regression.checks.limit_problems`, no excuse): how many
answers of each status break one, and which limits.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path
from typing import Any

# bench/ itself must not be on the path: bench/commonroad.py would shadow the commonroad package
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from planner_tools.commonroad import CommonRoadError  # noqa: E402
from planner_tools.evaluate import (  # noqa: E402 (after the path fix)
    VEHICLES,
    Settings,
    find_scenes,
    prepare,
    run_scene,
)

REQUESTS = ROOT / "tests" / "data" / "commonroad"


def scenes(xml: Path | None = None) -> list[Path]:
    """The shared requests, or the CommonRoad XML files of ``xml`` (e.g. ``bench/swap_ego.py``'s)."""
    if xml is not None:
        return [p for p in find_scenes([xml]) if not p.name.endswith(".json")]
    return sorted(p for p in REQUESTS.glob("*.json") if p.name != "index.json")


def request_of(path: Path, vehicle: str) -> dict[str, Any]:
    """The scene's first request as the closed loops send it (goal, speed limit, vehicle), with the
    largest budget (a loaded machine changes no answer)."""
    request = dict(prepare(path, Settings(vehicle=vehicle)).request)
    request["options"] = {**request["options"], "time_budget_ms": 60_000.0}
    return request


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--vehicle", choices=VEHICLES, default="car")
    parser.add_argument("--closed-loop", action="store_true", help="check every cycle of the closed loops")
    parser.add_argument("--xml", type=Path, help="the CommonRoad XML files in DIR instead of the requests")
    args = parser.parse_args(argv)
    if args.closed_loop:
        return closed_loop(args.vehicle, args.xml)

    from fastapi.testclient import TestClient

    from app.conversions import to_problem
    from app.main import create_app
    from app.models.planning import PlanningRequest
    from app.settings import Settings as AppSettings
    from tests.regression.checks import STATUSES, limit_problems, plan_problems, trajectory_of

    print("| scene | status | profile | follower | goal | breaks | vehicle limits |\n|" + "---|" * 7)
    broken = beyond = refused = 0
    paths = scenes(args.xml)
    with TestClient(create_app(AppSettings(log_level="warning", plan_processes=1))) as client:
        for path in paths:
            try:
                request = request_of(path, args.vehicle)
            except CommonRoadError as exc:  # a scene the converter refuses: no request to post
                refused += 1
                print(f"| {path.stem} | not converted: {exc} | | | | | |")
                continue
            answer = client.post("/v1/plan", json=request).json()
            problems = plan_problems(request, answer, STATUSES)
            problem = to_problem(PlanningRequest.model_validate(request))
            limits = limit_problems(problem, trajectory_of(answer))
            broken += bool(problems)
            beyond += bool(limits)
            diagnostics = answer["diagnostics"]
            follower = diagnostics.get("follower")
            named = "—" if follower is None else f"{follower['obstacle_id']} ({follower['reason']})"
            goal = diagnostics.get("goal")
            goal_text = (
                "—" if goal is None else goal["status"] + (f" ({goal['reason']})" if "reason" in goal else "")
            )
            print(
                f"| {path.stem} | {answer['status']} | {diagnostics['speed']['profile']} | {named} "
                f"| {goal_text} "
                f"| {'; '.join(problems)[:160] or '—'} | {'; '.join(limits)[:120] or '—'} |"
            )
    print(
        f"\n{broken} of {len(paths) - refused} answers break a check, {beyond} a vehicle limit (excused or "
        f"not); {refused} scenes not converted; vehicle: {args.vehicle}."
    )
    return 0


def closed_loop(vehicle: str, xml: Path | None = None) -> int:
    """Every cycle's answer of every scene's closed loop (as ``bench/commonroad.py`` drives it) against
    the vehicle's limits."""
    from planner_tools.sim import problem_at
    from tests.regression.checks import limit_problems

    cycles: Counter[str] = Counter()
    beyond: Counter[str] = Counter()
    kinds: Counter[str] = Counter()
    for path in scenes(xml):
        run = run_scene(path, Settings(vehicle=vehicle), keep=True)
        if run.result is None or run.prepared is None:
            print(f"{path.stem}: {run.outcome.error}", file=sys.stderr)
            continue
        broken = 0
        for step in run.result.steps:
            if step.trajectory is None:
                continue
            cycles[step.status] += 1
            # the cycle's own request (its ego: the measured steering angle the answer starts from)
            problems = limit_problems(problem_at(run.prepared.problem, step.state), step.trajectory)
            broken += bool(problems)
            beyond[step.status] += bool(problems)
            kinds.update(" ".join(p.split(" ")[:2]) for p in problems)
        print(
            f"{path.stem}: {len(run.result.steps)} cycles, {broken} beyond a vehicle limit", file=sys.stderr
        )
    per_status = ", ".join(f"{s} {beyond[s]} / {cycles[s]}" for s in sorted(cycles))
    print(f"{sum(beyond.values())} of {sum(cycles.values())} answers beyond a vehicle limit ({per_status})")
    print(f"limits broken: {dict(kinds)}; vehicle: {vehicle}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
