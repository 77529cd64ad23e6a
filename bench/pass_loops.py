"""Passing a slow vehicle within a wide lane, in closed loop on random scenes: ``python bench/pass_loops.py``
drives, per run, a car or a point-model vehicle up to a slow vehicle in a lane wide enough to pass it in
(several lanes of one direction as one, as the CommonRoad converter builds them; no ``road``), with, in
60 % of the runs where that side is wide enough, a second vehicle driving in the room on one side, and
prints how the runs went (asserts nothing).

A scene (seeded, so each run is reproducible by its seed): a straight, or an arc of radius 60–250 m; the
lane 1.75–6 m to either side of the reference; the ego on the reference at 5–14 m/s, its target speed
its own; the slow vehicle 4.5 m long, 1.6–2.5 m wide, at 0–3 m/s along the reference, 25–60 m ahead,
0–1 m to either side of it; the second vehicle 4.5 × 1.8 m at 3–15 m/s, 3.3 m to the side, starting
20 m behind to 40 m ahead of the ego. Each run replans every 0.1 s for ``--duration`` seconds
(:func:`planner_tools.sim.simulate`).

Printed: the cycles per status; of the runs whose slow vehicle is much slower than the target and leaves
room for the vehicle beside it (where the lane decision may pass it, ``passing_in_lane``), how many got
past it; and every run with a collision, a departure from the lane, a fallback, an error or ten cycles
stopped (its seed, statuses, end).

    python bench/pass_loops.py                         # 100 runs from seed 0
    python bench/pass_loops.py --runs 300 --seed 1000 --duration 14
"""

from __future__ import annotations

import collections
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner.problem import DynamicObstacle, Lane, PlanningProblem, Vehicle  # noqa: E402 (after the path fix)
from planner.reference import ReferenceLine, build_reference  # noqa: E402
from planner.roads import arc, straight, two_lane_problem  # noqa: E402
from planner_tools.loops import along_reference, seeded_loops  # noqa: E402

#: a run's footprint this far outside the lane [m] is a departure
DEPARTURE = 0.02
#: a run stopped for this many cycles is shown (nothing here blocks the lane for long)
STOPPED = 10


@dataclass(frozen=True)
class Scene:
    """A run's problem, where its slow vehicle starts [m] and how fast it drives [m/s], whether the lane
    decision may pass it (much slower than the target, room beside it), whether traffic drives beside."""

    problem: PlanningProblem
    slow_s: float
    slow_speed: float
    passable: bool
    beside: bool


def _along(
    ref: ReferenceLine, obstacle_id: str, s0: float, d: float, speed: float, width: float
) -> DynamicObstacle:
    """A 4.5 m long vehicle ``width`` [m] wide at offset ``d`` [m] along the reference from ``s0`` [m] at
    ``speed`` [m/s], predicted over 20 s."""
    t = np.linspace(0.0, 20.0, 81)
    return DynamicObstacle(obstacle_id, 4.5, width, along_reference(ref, t, s0 + speed * t, d))


def scene(seed: int) -> Scene:
    """The scene of ``seed`` (module docstring)."""
    rng = np.random.default_rng(seed)
    if rng.random() < 0.5:
        points = np.asarray(straight(300.0, step=0.5))
    else:
        radius = float(rng.uniform(60, 250))
        points = np.asarray(arc(radius, 300.0 / radius, step=0.5)) * np.array([1.0, rng.choice([-1.0, 1.0])])
    ref = build_reference(points)
    v0 = float(rng.uniform(5, 14))
    left, right = float(rng.uniform(1.75, 6.0)), float(rng.uniform(1.75, 6.0))
    slow_speed, slow_s, slow_d = (
        float(rng.uniform(0, 3)),
        float(rng.uniform(25, 60)),
        float(rng.uniform(-1, 1)),
    )
    slow_width = float(rng.uniform(1.6, 2.5))
    obstacles = [_along(ref, "slow", slow_s, slow_d, slow_speed, slow_width)]
    side = 1.0 if rng.random() < 0.5 else -1.0
    beside = bool(rng.random() < 0.6) and (left if side > 0 else right) >= 4.3
    if beside:
        obstacles.append(
            _along(ref, "beside", float(rng.uniform(-20, 40)), 3.3 * side, float(rng.uniform(3, 15)), 1.8)
        )
    vehicle = Vehicle(wheelbase=2.7, rear_axle_offset=1.35) if rng.random() < 0.5 else None
    problem = two_lane_problem(points, speed=v0, obstacles=tuple(obstacles), road=False, vehicle=vehicle)
    problem = replace(problem, lane=Lane(left, right))
    need = problem.vehicle.width + 2.0 * problem.options.lateral_margin
    room = max(left - slow_d - slow_width / 2, slow_d - slow_width / 2 + right) >= need
    passable = room and slow_speed < 0.5 * v0 and slow_speed < v0 - 2.0
    return Scene(problem, slow_s, slow_speed, passable, beside)


def main(argv: list[str] | None = None) -> int:
    past: collections.Counter[tuple[bool, bool]] = collections.Counter()
    for loop in seeded_loops(__doc__, 10.0, argv, scene, lambda sc: sc.problem):
        sc, m = loop.scene, loop.result.metrics
        slow_front = sc.slow_s + sc.slow_speed * m.sim_time + 2.25
        if sc.passable:
            past[(sc.beside, m.final_s - sc.problem.vehicle.rear_extent > slow_front)] += 1
        problems = loop.failures
        if loop.counts["stopped"] >= STOPPED:
            problems.append(f"stopped for {loop.counts['stopped']} cycles")
        if m.max_lane_departure > DEPARTURE:
            problems.append(f"{m.max_lane_departure:.2f} m out of the lane")
        loop.report(problems)
    for beside in (False, True):
        total = past[(beside, True)] + past[(beside, False)]
        label = "with traffic beside" if beside else "alone"
        print(f"  passable slow vehicle, {label}: {past[(beside, True)]} of {total} past it")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
