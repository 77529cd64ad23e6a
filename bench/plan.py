"""Planning benchmark: ``python bench/plan.py`` prints figures per stage (asserts nothing).

* the lateral QP alone on 200 knots (Δs = 0.5 m), warm-started, free and with an obstacle bound active;
* the speed stage alone (N = 80, Δt = 0.1 s) with a curvature dip and a leader;
* whole plans on an 8 s horizon with 3 obstacles (the demo U-turn with a parked car and a leader added,
  and a straight road), for the point model and for a car, median and p99, with the per-stage
  breakdown from the plan's diagnostics;
* the same scenes with a goal (a stop inside a region, a region in a time window above the target, a
  region beside the reference), each planned alternately with and without its goal, so that both see the
  same machine (``--goals`` runs only these).

Targets (issue 3): lateral QP ≤ 3 ms median; speed ≤ 10 ms median; plan ≤ 25 ms median, ≤ 60 ms p99.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner.goal import Goal, GoalPolygon
from planner.pipeline import plan
from planner.problem import (
    CircleObstacle,
    DynamicObstacle,
    Ego,
    Lane,
    Options,
    PlanningProblem,
    PolygonObstacle,
    Vehicle,
)
from planner.roads import demo_problem, straight
from planner.thread_solvers import new_solvers
from solvers.lateral_qp import LateralQPProblem, LateralQPSolver
from solvers.speed_problem import SpeedProblem


def timings(fn: Callable[[], object], repeats: int) -> np.ndarray:
    fn()
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out.append(1e3 * (time.perf_counter() - t0))
    return np.asarray(out)


def line(name: str, ms: np.ndarray, target: str = "") -> None:
    print(
        f"{name:44s} median {np.median(ms):7.2f} ms  p90 {np.percentile(ms, 90):7.2f}  "
        f"p99 {np.percentile(ms, 99):7.2f}  {target}"
    )


def bench_lateral() -> None:
    n, ds = 200, 0.5
    s = np.arange(n) * ds
    ref = 1.5 / (1.0 + np.exp(-(s - 40.0) / 4.0))
    solver = LateralQPSolver()
    free = LateralQPProblem(ds=ds, d_lower=np.full(n, -3.0), d_upper=np.full(n, 3.0), d_ref=ref, jerk_max=0.5)
    lower = np.where((s > 50) & (s < 60), 1.0, -3.0)
    pushed = replace(free, d_lower=lower, d_ref=np.zeros(n))
    for name, problem in (("lateral QP, 200 knots, free", free), ("lateral QP, 200 knots, obstacle", pushed)):
        line(name, timings(lambda p=problem: solver.solve(p), 200), "(target ≤ 3 ms median)")


def bench_speed() -> None:
    solver = new_solvers().speed  # configured as the pipeline configures it
    limit_s = np.linspace(0.0, 150.0, 301)
    limit_v = np.where((limit_s > 40) & (limit_s < 60), 6.0, 15.0)
    t = np.arange(81) * 0.1
    problem = SpeedProblem(
        dt=0.1,
        steps=80,
        v0=12.0,
        limit_s=limit_s,
        limit_v=limit_v,
        v_target=15.0,
        a_min=-6.0,
        a_max=2.5,
        jerk_max=8.0,
        s_upper=40.0 + 8.0 * t,
    )
    line(
        "speed profile, N = 80 (dip + leader)",
        timings(lambda: solver.solve(problem), 100),
        "(target ≤ 10 ms)",
    )


def scenes() -> dict[str, PlanningProblem]:
    demo = demo_problem()
    t = np.arange(0.0, 8.01, 0.5)
    leader = DynamicObstacle("leader", 4.5, 1.8, np.column_stack((t, -5.0 + 3.0 * t, 0 * t, 0 * t)))
    parked = PolygonObstacle("parked", np.array([[-8.0, -3.4], [-3.0, -3.4], [-3.0, -1.6], [-8.0, -1.6]]))
    u_turn = replace(demo, obstacles=(*demo.obstacles, parked, leader))
    road = straight(300.0, step=5.0)
    lead2 = DynamicObstacle("leader", 4.5, 1.8, np.column_stack((t, 60.0 + 8.0 * t, 0 * t, 0 * t)))
    car = PolygonObstacle("parked", np.array([[40.0, -3.0], [45.0, -3.0], [45.0, -1.2], [40.0, -1.2]]))
    cone = CircleObstacle("cone", np.array([90.0, 2.5]), 0.5)
    highway = PlanningProblem(
        road,
        Lane(3.5, 3.5),
        Ego(10.0, 0.0, 0.0, 12.0),
        (car, cone, lead2),
        Vehicle(),
        Options(target_speed=15.0),
    )
    scenes = {"demo U-turn + parked car + leader": u_turn, "straight road, 3 obstacles": highway}
    # the same scenes for a car (wheelbase 2.7 m, rear axle 1.35 m behind the centre, 0.5 rad/s steering)
    car = {"wheelbase": 2.7, "rear_axle_offset": 1.35, "max_steering_rate": 0.5}
    for name, problem in list(scenes.items()):
        scenes[f"{name}, a car"] = replace(problem, vehicle=replace(problem.vehicle, **car))
    return scenes


def bench_plans() -> None:
    for name, problem in scenes().items():
        result = plan(problem)
        stages: dict[str, list[float]] = {}
        totals = []
        for _ in range(100):
            t0 = time.perf_counter()
            r = plan(problem)
            totals.append(1e3 * (time.perf_counter() - t0))
            for key, value in r.diagnostics.timing_ms.items():
                stages.setdefault(key, []).append(value)
        line(f"plan: {name} [{result.status}]", np.asarray(totals), "(target ≤ 25 ms median, ≤ 60 ms p99)")
        breakdown = "  ".join(f"{k} {statistics.median(v):.1f}" for k, v in stages.items() if k != "total")
        print(f"    median per stage [ms]: {breakdown}")


def _box(x0: float, x1: float, y0: float, y1: float) -> GoalPolygon:
    return GoalPolygon(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))


def goal_scenes() -> dict[str, tuple[PlanningProblem, Goal]]:
    """Scenes of :func:`scenes` and a goal for each: (problem without it, goal)."""
    base = scenes()
    highway = base["straight road, 3 obstacles"]
    u_turn = base["demo U-turn + parked car + leader"]
    hurry = replace(highway, options=replace(highway.options, speed_limit=18.0))
    return {
        "straight, stop 50–60 m ahead": (highway, Goal(_box(60.0, 70.0, -1.75, 1.75), speed=(0.0, 0.0))),
        "straight, 6–8 s window, limit 18": (hurry, Goal(_box(85.0, 100.0, -1.75, 1.75), time=(6.0, 8.0))),
        "straight, region beside the lane centre": (highway, Goal(_box(60.0, 80.0, 1.2, 3.5))),
        "U-turn, the turn's exit in 4–9 s": (u_turn, Goal(_box(2.0, 12.0, 4.0, 14.0), time=(4.0, 9.0))),
    }


def bench_goals(repeats: int = 100) -> None:
    """Each goal scene planned alternately without and with its goal: medians and p99 of both."""
    for name, (problem, goal) in goal_scenes().items():
        with_goal = replace(problem, goal=goal)
        report = plan(with_goal).diagnostics.goal
        plan(problem)
        plain, aimed = [], []
        for _ in range(repeats):
            for problem_, out in ((problem, plain), (with_goal, aimed)):
                t0 = time.perf_counter()
                plan(problem_)
                out.append(1e3 * (time.perf_counter() - t0))
        a, b = np.asarray(plain), np.asarray(aimed)
        status = "" if report is None else report.status.value
        print(
            f"goal: {name:42s} without {np.median(a):6.1f} / p99 {np.percentile(a, 99):6.1f} ms   "
            f"with {np.median(b):6.1f} / p99 {np.percentile(b, 99):6.1f} ms   [{status}]"
        )


def main() -> None:
    print(f"{os.cpu_count()} cores; every figure wall time in this process")
    if "--goals" in sys.argv[1:]:
        bench_goals()
        return
    bench_lateral()
    bench_speed()
    bench_plans()
    bench_goals()


if __name__ == "__main__":
    main()
