"""Vehicles from behind: with a speed limit above the target the plan speeds up to keep ahead of one;
one that cannot be escaped is named in the answer with a typed reason, and the plan does not brake into
it.

Contacts are judged here from the trajectory and the obstacle's prediction directly (footprints and
boxes as polygons at the same times), not with the planner's own checks.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest
import shapely
from scenario_roads import Road, arc_piece, follow_prediction, straight_piece
from spies import started_work
from traffic import LANE, ROAD, car

from planner.collision import box_corners, prediction_at
from planner.config import DEFAULT_CONFIG
from planner.follower import FollowerReason
from planner.pipeline import plan
from planner.problem import DynamicObstacle, Ego, Lane, Options, PlanningProblem, Vehicle
from planner.result import PlanResult
from planner.speed import ProfileKind
from solvers.speed_problem import SpeedProblem
from solvers.speed_sqp import SpeedSolver
from tests.regression.checks import limit_problems


def _contacts(problem: PlanningProblem, result: PlanResult, obstacle: DynamicObstacle) -> np.ndarray:
    """The times [s] at which the trajectory's footprint meets the obstacle's predicted box."""
    traj, veh = result.trajectory, problem.vehicle
    ours = shapely.polygons(box_corners(traj.x, traj.y, traj.heading, veh.length, veh.width))
    state = prediction_at(obstacle, traj.t)
    theirs = shapely.polygons(
        box_corners(state[:, 0], state[:, 1], state[:, 2], obstacle.length, obstacle.width)
    )
    return np.asarray(traj.t[shapely.intersects(ours, theirs)])


def _single_lane(limit: float | None, ego_speed: float = 10.0) -> tuple[PlanningProblem, DynamicObstacle]:
    """The ego at 10 m/s with a target of 10 in a single lane; a car at 16 m/s, 12 m behind (front to
    rear), that does not react."""
    behind = car("behind", 30.0 - 4.5 - 12.0, 16.0)
    options = Options(target_speed=10.0, speed_limit=limit)
    problem = PlanningProblem(
        ROAD, Lane(1.75, 1.75), Ego(30.0, 0.0, 0.0, ego_speed), (behind,), Vehicle(), options
    )
    return problem, behind


def test_with_a_speed_limit_above_the_target_the_plan_speeds_up_ahead_of_a_faster_car_behind() -> None:
    problem, behind = _single_lane(limit=18.0)
    result = plan(problem)
    assert result.status == "ok", result.message
    assert _contacts(problem, result, behind).size == 0
    traj = result.trajectory
    assert traj.v.max() > 16.0  # faster than the car behind for a while
    assert traj.v.max() <= 18.0 + 0.05  # never above the speed limit
    assert result.diagnostics.follower is None
    assert limit_problems(problem, traj) == []
    # without the car behind it cruises at the target: the speed limit alone changes nothing
    alone = plan(PlanningProblem(ROAD, problem.lane, problem.ego, (), problem.vehicle, problem.options))
    assert alone.status == "ok" and np.allclose(alone.trajectory.v, 10.0, atol=1e-3)


def test_at_a_speed_limit_equal_to_the_target_the_answer_names_the_car_behind_and_does_not_brake() -> None:
    problem, behind = _single_lane(limit=10.0)
    result = plan(problem)
    contacts = _contacts(problem, result, behind)
    assert result.status == "fallback" and contacts.size > 0
    follower = result.diagnostics.follower
    assert follower is not None
    assert follower.obstacle_id == "behind"
    assert follower.reason is FollowerReason.SPEED_LIMIT
    assert follower.t == pytest.approx(contacts[0])
    traj = result.trajectory
    assert traj.a.min() > -0.5 and traj.v.min() >= 10.0 - 1e-3  # no braking in front of it
    assert limit_problems(problem, traj) == []
    assert result.diagnostics.speed_profile is not ProfileKind.BRAKING


def test_a_car_behind_too_fast_for_the_vehicles_acceleration_is_named_for_it() -> None:
    problem, _ = _single_lane(limit=30.0)
    weak = Vehicle(max_speed=30.0, max_acceleration=0.3)
    result = plan(PlanningProblem(ROAD, problem.lane, problem.ego, problem.obstacles, weak, problem.options))
    follower = result.diagnostics.follower
    assert result.status == "fallback" and follower is not None
    assert follower.reason is FollowerReason.ACCELERATION
    assert result.trajectory.a.min() > -0.5


def test_a_car_behind_that_a_curve_ahead_keeps_closing_on_is_named_for_the_curvature() -> None:
    """A 25 m curve 40 m ahead (about 8 m/s within the lateral limit), the ego at 14 m/s, a recorded car
    12 m behind at 14 m/s that does not slow for it: every answer is within the limits, and the car
    behind is named for the curvature."""
    road = Road([straight_piece(80.0), arc_piece(25.0, np.pi / 2), straight_piece(80.0)])
    x, y, heading = road.pose(40.0)
    behind = DynamicObstacle("behind", 4.5, 1.8, follow_prediction(road, 40.0 - 16.5, 14.0, 8.0))
    options = Options(target_speed=14.0, speed_limit=20.0)
    ego = Ego(x, y, heading, 14.0)
    problem = PlanningProblem(road.polyline(1.0), Lane(3.5, 3.5), ego, (behind,), Vehicle(), options)
    result = plan(problem)
    assert limit_problems(problem, result.trajectory) == []
    follower = result.diagnostics.follower
    assert result.status == "fallback" and follower is not None
    assert follower.reason is FollowerReason.CURVATURE
    assert _contacts(problem, result, behind)[0] == pytest.approx(follower.t)


def test_a_car_behind_that_a_leader_ahead_keeps_it_from_escaping_is_named_for_what_is_ahead() -> None:
    """A leader 10 m ahead at 10 m/s and a car 12 m behind at 16 m/s, speed limit 25: getting away
    would run into the leader, so the answer keeps behind it and names the car behind for it."""
    problem, behind = _single_lane(limit=25.0)
    leader = car("leader", 30.0 + 4.5 + 10.0, 10.0)
    crowded = PlanningProblem(
        ROAD, problem.lane, problem.ego, (behind, leader), problem.vehicle, problem.options
    )
    result = plan(crowded)
    follower = result.diagnostics.follower
    assert result.status == "fallback" and follower is not None
    assert follower.obstacle_id == "behind" and follower.reason is FollowerReason.AHEAD
    assert _contacts(crowded, result, leader).size == 0
    assert limit_problems(crowded, result.trajectory) == []


def test_the_car_behind_in_the_next_lane_is_never_named() -> None:
    problem, _ = _single_lane(limit=10.0)
    beside = car("beside", 30.0 - 4.5 - 12.0, 16.0, y=-3.5)
    result = plan(PlanningProblem(ROAD, LANE, problem.ego, (beside,), problem.vehicle, problem.options))
    assert result.status == "ok" and result.diagnostics.follower is None


def test_the_second_profile_solved_beside_the_first_on_a_spare_thread_is_the_same(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A car behind closing on the ego (it cannot be escaped at the target): the profile with the
    emergency jerk, needed after the first, starts on the spare thread beside it; the answer is the one
    planned without a spare thread, where the same profile is solved after the first."""
    problem, _ = _single_lane(limit=10.0)
    started = started_work(monkeypatch)
    solves: list[float] = []
    solve = SpeedSolver.solve

    def counted_solve(self: SpeedSolver, sp: SpeedProblem, **kwargs: Any) -> Any:
        solves.append(sp.jerk_max)
        return solve(self, sp, **kwargs)

    monkeypatch.setattr(SpeedSolver, "solve", counted_solve)
    alone = plan(problem, replace(DEFAULT_CONFIG, speculate=False))
    assert started == [] and solves == [8.0, 30.0]  # the emergency jerk's profile after the first
    solves.clear()
    beside = plan(problem)
    assert started == ["emergency"] and sorted(solves) == [8.0, 30.0]
    assert (beside.status, beside.message) == (alone.status, alone.message)
    for name in ("t", "x", "y", "v", "a", "heading", "curvature", "s", "d"):
        np.testing.assert_array_equal(getattr(beside.trajectory, name), getattr(alone.trajectory, name))
