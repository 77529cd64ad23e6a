"""Vehicles coming from behind: the speed profile keeps ahead of them (a soft lower space-time bound), gives
way to what is ahead when both cannot be kept, and the fallback does not brake into them.

Before the lower bound, the first scene here was a ``fallback``: the profile slowed to the target speed,
the checks found the faster car behind driving through it, and full braking was hit too.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from planner.pipeline import PlanResult, plan, static_shapes
from planner.problem import DynamicObstacle, Ego, Lane, Options, PlanningProblem, PolygonObstacle, Vehicle
from planner.reference import build_reference
from planner.roads import straight
from planner.validation import Violation, ViolationKind, trajectory_violations

ROAD = straight(300.0, step=5.0)
LANE = Lane(3.5, 3.5)
T = np.arange(0.0, 8.01, 0.5)


def _car(name: str, x0: float, speed: float, y: float | np.ndarray = 0.0) -> DynamicObstacle:
    """A 4.5 m × 1.8 m car along x from ``x0`` [m] at ``speed`` [m/s], at ``y`` [m] (one per time of T)."""
    return DynamicObstacle(name, 4.5, 1.8, np.column_stack((T, x0 + speed * T, y + 0 * T, 0 * T)))


def _violations(problem: PlanningProblem, result: PlanResult) -> list[Violation]:
    ref = build_reference(problem.reference_line)
    return trajectory_violations(ref, problem, result.trajectory, static_shapes(problem))


def _min_gap(result: PlanResult, x0: float, speed: float) -> float:
    """Smallest distance [m] from our rear to the front of a car from ``x0`` at ``speed`` (both 4.5 m)."""
    traj = result.trajectory
    return float(np.min((traj.x - 2.25) - (x0 + speed * traj.t + 2.25)))


def test_keeps_a_headway_ahead_of_a_faster_car_behind_in_the_same_lane() -> None:
    # ego at 10 m/s with a target of 14; a car 15 m behind at 14 m/s that does not react
    alone = PlanningProblem(ROAD, LANE, Ego(30.0, 0.0, 0.0, 10.0), (), Vehicle(), Options(target_speed=14.0))
    problem = replace(alone, obstacles=(_car("behind", 15.0, 14.0),))
    result = plan(problem)
    assert result.status == "ok", result.message
    assert _violations(problem, result) == []  # including the car behind
    assert np.max(result.trajectory.v) <= 14.0 + 1e-6  # the target speed stays a cap
    # the comfortable speed-up alone lets it come within 3–4 m; the bound keeps about its headway
    assert _min_gap(plan(alone), 15.0, 14.0) < 4.0
    assert _min_gap(result, 15.0, 14.0) > 5.0


def test_the_target_speed_stays_a_cap_with_a_faster_car_behind() -> None:
    # target 8 and a car behind at 14 m/s: keeping ahead would need 14 m/s; the plan does not speed
    # up past the target, so the answer is a fallback that says who hits it, and it does not brake hard
    problem = PlanningProblem(
        ROAD,
        LANE,
        Ego(30.0, 0.0, 0.0, 10.0),
        (_car("behind", 15.0, 14.0),),
        Vehicle(),
        Options(target_speed=8.0),
    )
    result = plan(problem)
    assert result.status == "fallback"
    assert "hit from behind" in result.message
    assert np.max(result.trajectory.v) <= 10.0 + 1e-6
    assert np.min(result.trajectory.v) >= 8.0 - 0.1  # never braking below the target into it


def test_a_car_behind_in_the_next_lane_changes_nothing() -> None:
    base = PlanningProblem(ROAD, LANE, Ego(30.0, 0.0, 0.0, 10.0), (), Vehicle(), Options(target_speed=8.0))
    beside = replace(base, obstacles=(_car("next lane", 15.0, 14.0, y=-5.0),))
    alone, passed = plan(base), plan(beside)
    assert alone.status == passed.status == "ok"
    assert _violations(beside, passed) == []
    assert np.array_equal(alone.trajectory.x, passed.trajectory.x)
    assert np.array_equal(alone.trajectory.v, passed.trajectory.v)


def test_a_car_that_overtakes_and_cuts_in_ahead_is_not_chased() -> None:
    # from 10 m behind in the next lane at 16 m/s, into ours between 3 and 4 s, well ahead of us by then
    y = np.interp(T, [0.0, 3.0, 4.0, 8.0], [-3.5, -3.5, 0.0, 0.0])
    problem = PlanningProblem(
        ROAD,
        LANE,
        Ego(30.0, 0.0, 0.0, 8.0),
        (_car("overtaker", 20.0, 16.0, y=y),),
        Vehicle(),
        Options(target_speed=8.0),
    )
    result = plan(problem)
    assert result.status == "ok", result.message
    assert _violations(problem, result) == []
    assert np.max(result.trajectory.v) < 8.1  # not chasing it to get ahead again


def test_when_braking_is_hit_from_behind_the_fallback_keeps_the_speed() -> None:
    # a leader 14 m ahead and a car 9 m behind, all at 15 m/s: the headway to the leader asks for braking,
    # which the car behind (recorded, it does not react) would drive into; keeping the speed hits nothing
    obstacles = (_car("leader", 44.0, 15.0), _car("behind", 21.0, 15.0))
    problem = PlanningProblem(
        ROAD, LANE, Ego(30.0, 0.0, 0.0, 15.0), obstacles, Vehicle(), Options(target_speed=15.0)
    )
    result = plan(problem)
    assert result.status == "fallback"
    assert "hit from behind" in result.message and "keeping the speed" in result.message
    assert result.violations == ()
    assert _violations(problem, result) == []
    assert np.allclose(result.trajectory.v, 15.0, atol=1e-6)


def test_a_block_ahead_wins_over_a_car_behind() -> None:
    # a wall across the road 50 m ahead and a car close behind: stopping before the wall comes first
    wall = PolygonObstacle("wall", np.array([[80.0, -4.0], [82.0, -4.0], [82.0, 4.0], [80.0, 4.0]]))
    problem = PlanningProblem(
        ROAD,
        LANE,
        Ego(30.0, 0.0, 0.0, 8.0),
        (wall, _car("behind", 20.0, 8.0)),
        Vehicle(),
        Options(target_speed=8.0),
    )
    result = plan(problem)
    assert result.status in ("stopped", "fallback")
    hits = [(v.kind, v.obstacle_id) for v in _violations(problem, result)]
    assert (ViolationKind.HITS_OBSTACLE, "wall") not in hits
    assert np.all(result.trajectory.x + 0.5 * Vehicle().length < 80.0)
    assert result.trajectory.v[-1] < 1e-3
