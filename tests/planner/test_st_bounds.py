"""Which obstacles stay put, and the space-time bounds the moving ones put on the speed profile.

Vehicles coming from behind: the speed profile keeps ahead of them (a soft lower space-time bound) and
gives way to what is ahead when both cannot be kept (the fallback's side: tests/planner/test_fallback.py).
Before the lower bound, the first scene here was a ``fallback``: the profile slowed to the target speed,
the checks found the faster car behind driving through it, and full braking was hit too.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from traffic import LANE, ROAD, T, car, violations

from planner.config import DEFAULT_CONFIG
from planner.pipeline import plan
from planner.problem import (
    CircleObstacle,
    DynamicObstacle,
    Ego,
    Options,
    PlanningProblem,
    PolygonObstacle,
    Vehicle,
)
from planner.reference import build_reference
from planner.result import PlanResult
from planner.st_bounds import followers, moving_obstacles, space_time_bounds, static_shapes
from planner.trajectory import Path, frenet_path
from planner.validation import Violation

REF = build_reference(ROAD)
#: the speed profile's knot times [s]
KNOTS = np.arange(81) * 0.1


def _path(s0: float = 30.0, s1: float = 250.0) -> Path:
    s = np.arange(s0, s1 + 1e-9, 0.5)
    return frenet_path(REF, s, 0.0 * s, 0.0 * s, 0.0 * s)


def _problem(*obstacles: DynamicObstacle | PolygonObstacle | CircleObstacle) -> PlanningProblem:
    return PlanningProblem(
        ROAD, LANE, Ego(30.0, 0.0, 0.0, 10.0), obstacles, Vehicle(), Options(target_speed=14.0)
    )


def test_an_obstacle_that_stays_put_over_the_horizon_is_static() -> None:
    parked = DynamicObstacle("parked", 4.5, 1.8, np.array([[0.0, 60.0, 0.0, 0.0], [8.0, 60.2, 0.0, 0.0]]))
    leaving = DynamicObstacle(
        "leaving", 4.5, 1.8, np.array([[0.0, 60.0, 3.0, 0.0], [8.0, 60.0, 3.0, 0.0], [9.0, 90.0, 3.0, 0.0]])
    )
    cone = CircleObstacle("cone", np.array([50.0, 1.0]), 0.3)
    problem = _problem(parked, leaving, cone, car("mover", 80.0, 5.0))
    assert [ob_id for ob_id, _ in static_shapes(problem)] == ["parked", "leaving", "cone"]  # within 8 s
    assert [ob.id for ob in moving_obstacles(problem)] == ["mover"]
    longer = replace(problem, options=replace(problem.options, horizon_time=10.0))
    assert [ob.id for ob in moving_obstacles(longer)] == ["leaving", "mover"]


def test_only_the_cars_behind_the_ego_at_the_start_are_followers() -> None:
    movers = [car("ahead", 40.0, 8.0), car("behind", 15.0, 14.0), car("beside behind", 20.0, 14.0, y=-3.5)]
    assert [ob.id for ob in followers(REF, movers, 30.0)] == ["behind", "beside behind"]


def test_a_leader_ahead_bounds_how_far_the_ego_may_be_a_headway_later() -> None:
    """σ_max(t) stops the footprint (obstacle_margin around it) short of where the leader's box was a
    headway earlier, less stop_gap, to within a knot of the path."""
    leader = car("leader", 60.0, 8.0)
    path = _path()
    bounds = space_time_bounds(REF, path, _problem(leader), KNOTS, 30.0)
    assert bounds.lower is None and bounds.upper is not None
    c = DEFAULT_CONFIG
    seen = np.maximum(KNOTS - c.speed.headway, 0.0)
    rear = 60.0 + 8.0 * seen - 2.25  # the leader's rear then [m]
    expected = rear - (2.25 + c.obstacle_margin) - 30.0 - c.stop_gap  # our centre along the path
    assert np.all(bounds.upper <= expected + 1e-9)
    assert np.all(bounds.upper >= expected - 0.5 - 1e-9)  # one knot


def test_a_car_behind_bounds_the_ego_from_below_not_from_above() -> None:
    bounds = space_time_bounds(REF, _path(), _problem(car("behind", 15.0, 14.0)), KNOTS, 30.0)
    assert bounds.upper is not None and np.all(np.isinf(bounds.upper))  # not followed
    assert bounds.lower is not None and np.all(np.diff(bounds.lower[np.isfinite(bounds.lower)]) >= 0.0)
    # ahead of its front for the follower headway, plus stop_gap
    c = DEFAULT_CONFIG
    met = np.isfinite(bounds.lower)
    front = 15.0 + 14.0 * np.minimum(KNOTS + c.speed.follower_headway, T[-1]) + 2.25  # held after 8 s
    expected = front + 2.25 + c.obstacle_margin - 30.0 + c.stop_gap  # our centre along the path
    assert np.all(bounds.lower[met] >= expected[met] - 1e-9)
    assert np.all(bounds.lower[met] <= expected[met] + 0.5 + 1e-9)  # one knot
    assert met[-1] and not met[0]  # from when it first meets the footprint on


def test_an_obstacle_far_from_the_path_bounds_nothing() -> None:
    far = DynamicObstacle("far", 4.5, 1.8, np.column_stack((T, 60.0 + 8.0 * T, 40.0 + 0 * T, 0 * T)))
    bounds = space_time_bounds(REF, _path(), _problem(far), KNOTS, 30.0)
    assert (bounds.upper, bounds.lower) == (None, None)


@pytest.mark.parametrize("margin", [0.3, 1.5])
def test_the_footprint_keeps_the_configured_obstacle_margin(margin: float) -> None:
    config = replace(DEFAULT_CONFIG, obstacle_margin=margin)
    bounds = space_time_bounds(REF, _path(), _problem(car("leader", 60.0, 2.0)), KNOTS, 30.0, config)
    assert bounds.upper is not None
    expected = 60.0 - 2.25 - (2.25 + margin) - 30.0 - DEFAULT_CONFIG.stop_gap  # where it is at the start
    assert expected - 0.5 - 1e-9 <= bounds.upper[0] <= expected + 1e-9


def _violations(problem: PlanningProblem, result: PlanResult) -> list[Violation]:
    return violations(problem, result.trajectory)


def _min_gap(result: PlanResult, x0: float, speed: float) -> float:
    """Smallest distance [m] from our rear to the front of a car from ``x0`` at ``speed`` (both 4.5 m)."""
    traj = result.trajectory
    return float(np.min((traj.x - 2.25) - (x0 + speed * traj.t + 2.25)))


def test_keeps_a_headway_ahead_of_a_faster_car_behind_in_the_same_lane() -> None:
    # ego at 10 m/s with a target of 14; a car 15 m behind at 14 m/s that does not react
    alone = PlanningProblem(ROAD, LANE, Ego(30.0, 0.0, 0.0, 10.0), (), Vehicle(), Options(target_speed=14.0))
    problem = replace(alone, obstacles=(car("behind", 15.0, 14.0),))
    result = plan(problem)
    assert result.status == "ok", result.message
    assert _violations(problem, result) == []  # including the car behind
    assert np.max(result.trajectory.v) <= 14.0 + 1e-6  # the target speed stays a cap
    # the comfortable speed-up alone lets it come within 3–4 m; the bound keeps about its headway
    assert _min_gap(plan(alone), 15.0, 14.0) < 4.0
    assert _min_gap(result, 15.0, 14.0) > 5.0


def test_a_car_behind_in_the_next_lane_changes_nothing() -> None:
    base = PlanningProblem(ROAD, LANE, Ego(30.0, 0.0, 0.0, 10.0), (), Vehicle(), Options(target_speed=8.0))
    beside = replace(base, obstacles=(car("next lane", 15.0, 14.0, y=-5.0),))
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
        (car("overtaker", 20.0, 16.0, y=y),),
        Vehicle(),
        Options(target_speed=8.0),
    )
    result = plan(problem)
    assert result.status == "ok", result.message
    assert _violations(problem, result) == []
    assert np.max(result.trajectory.v) < 8.1  # not chasing it to get ahead again
