"""Which obstacles stay put, and the space-time bounds the moving ones put on the speed profile.

Vehicles coming from behind: the speed profile keeps ahead of them (a soft lower space-time bound) and
gives way to what is ahead when both cannot be kept (the fallback's side: tests/planner/test_fallback.py).
Before the lower bound, the first scene here was a ``fallback``: the profile slowed to the target speed,
the checks found the faster car behind driving through it, and full braking was hit too.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from traffic import LANE, ROAD, T, car, violations

from planner.collision import STATIC_MOTION, is_static, prediction_at
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
from planner.st_bounds import (
    Along,
    crossings,
    followers,
    frenet_extents,
    moving_obstacles,
    space_time_bounds,
    static_shapes,
)
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


def _turning_in(name: str, x0: float, x_join: float, speed: float) -> DynamicObstacle:
    """A car on a side road 30 m to the right of the reference at ``x0`` [m] that drives straight to the
    road at ``x_join`` [m] in 3 s, then along it at ``speed`` [m/s]."""
    t = np.array([0.0, 3.0, 8.0])
    x = np.array([x0, x_join, x_join + 5.0 * speed])
    heading = np.arctan2(30.0, x_join - x0)
    return DynamicObstacle(name, 4.5, 1.8, np.column_stack((t, x, [-30.0, 0.0, 0.0], [heading, 0.0, 0.0])))


def test_a_car_turning_in_is_behind_or_ahead_where_it_joins_the_road_not_where_it_starts() -> None:
    """Where a car on a side road projects onto the reference says nothing of where it will drive: it is
    judged where it first comes within JOIN_REACH of the reference (seen on a recorded junction: a car
    whose first projection lay 70 m ahead turned in 35 m behind the ego and was followed as a leader, so
    nothing kept the ego ahead of it)."""
    behind = _turning_in("turns in behind", x0=45.0, x_join=15.0, speed=12.0)  # first projects ahead
    ahead = _turning_in("turns in ahead", x0=15.0, x_join=45.0, speed=8.0)  # first projects behind
    assert [ob.id for ob in followers(REF, [behind, ahead], 30.0)] == ["turns in behind"]
    # one that stays on its side road is judged where it is
    parallel = DynamicObstacle(
        "side road", 4.5, 1.8, np.column_stack((T, 10.0 + 9.0 * T, -30.0 + 0 * T, 0 * T))
    )
    assert [ob.id for ob in followers(REF, [parallel], 30.0)] == ["side road"]
    assert [ob.id for ob in followers(REF, [parallel], 5.0)] == []
    # the leader's bound holds the ego behind where it turns in; none is put on the follower
    bounds = space_time_bounds(REF, _path(), _problem(ahead), KNOTS, 30.0)
    assert bounds.lower is None and bounds.upper is not None
    assert float(bounds.upper[-1]) < 45.0 + 5.0 * 8.0
    bounds = space_time_bounds(REF, _path(), _problem(behind), KNOTS, 30.0)
    assert bounds.upper is None and bounds.lower is not None


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
    assert bounds.upper is None or np.all(np.isinf(bounds.upper))  # not followed (None: nothing bounds)
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


def test_a_problem_asked_again_gets_its_own_static_flags() -> None:
    """The flags are kept for the last problem only: another problem (here one whose longer horizon
    makes an obstacle move) is never answered with them, and asking again changes nothing."""
    leaving = DynamicObstacle(
        "leaving", 4.5, 1.8, np.array([[0.0, 60.0, 3.0, 0.0], [8.0, 60.0, 3.0, 0.0], [9.0, 90.0, 3.0, 0.0]])
    )
    problem = _problem(leaving, car("mover", 80.0, 5.0))
    longer = replace(problem, options=replace(problem.options, horizon_time=10.0))
    for _ in range(2):
        assert [ob.id for ob in moving_obstacles(problem)] == ["mover"]
        assert [ob.id for ob in moving_obstacles(longer)] == ["leaving", "mover"]
        assert [ob_id for ob_id, _ in static_shapes(problem)] == ["leaving"]


def _is_static_by_poses(obstacle: DynamicObstacle, horizon: float) -> bool:
    """The definition, through the poses' positions as prediction_at gives them."""
    pred = obstacle.prediction
    inside = pred[(pred[:, 0] >= 0.0) & (pred[:, 0] <= horizon)]
    states = np.vstack((prediction_at(obstacle, np.array([0.0, horizon]))[:, :2], inside[:, 1:3]))
    return bool(np.max(np.linalg.norm(states - states[0], axis=1)) < STATIC_MOTION)


def test_is_static_and_the_headings_agree_with_their_definitions() -> None:
    """``is_static`` (positions only) is the definition through ``prediction_at``'s poses, and the
    headings ``prediction_at`` interpolates are ``np.unwrap``'s, with and without a wrap."""
    rng = np.random.default_rng(3)
    for k in range(200):
        t = np.cumsum(rng.uniform(0.05, 2.0, 6)) - 2.0
        drift = rng.choice([0.0, 0.05, 0.2, 1.0])
        xy = 50.0 + np.cumsum(rng.normal(0.0, drift, (6, 2)), axis=0)
        heading = rng.uniform(-np.pi, np.pi, 6) if k % 2 else np.linspace(0.0, 0.5, 6)
        ob = DynamicObstacle("o", 4.0, 2.0, np.column_stack((t, xy, heading)))
        for horizon in (0.5, 3.0, 8.0):
            assert is_static(ob, horizon) == _is_static_by_poses(ob, horizon)
        times = np.linspace(t[0] - 1.0, t[-1] + 1.0, 50)
        expected = np.interp(times, t, np.unwrap(heading))
        assert np.array_equal(prediction_at(ob, times)[:, 2], expected)


def test_boxes_mapped_only_near_the_path_give_the_same_bounds() -> None:
    """The moving obstacles' boxes are mapped only at the times they come near the path: the bounds are
    those of every box mapped (a far box meets nothing)."""
    leader = car("leader", 60.0, 8.0)
    behind = car("behind", 10.0, 16.0)
    crossing = DynamicObstacle(
        "crossing", 4.5, 1.8, np.array([[0.0, 120.0, -60.0, np.pi / 2], [8.0, 120.0, 60.0, np.pi / 2]])
    )
    far = car("far", 40.0, 10.0, y=40.0)
    problem = _problem(leader, behind, crossing, far)
    path = _path()
    fast = space_time_bounds(REF, path, problem, KNOTS, 30.0)

    near = Along.near

    def everywhere(self: Along, movers: list[DynamicObstacle], t: np.ndarray) -> Any:
        close_ones, states, close = near(self, movers, t)
        return close_ones, states, np.ones_like(close)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(Along, "near", everywhere)
        full = space_time_bounds(REF, path, problem, KNOTS, 30.0)
    assert fast.upper is not None and full.upper is not None and fast.lower is not None
    assert full.lower is not None
    assert np.array_equal(fast.upper, full.upper)
    assert np.array_equal(fast.lower, full.lower)
    extents = frenet_extents(REF, [crossing], [prediction_at(crossing, KNOTS)], np.arange(81)[None, :] < 40)
    whole = frenet_extents(REF, [crossing], [prediction_at(crossing, KNOTS)])
    for part, every in zip(extents, whole, strict=True):
        assert np.array_equal(part[:, :40], every[:, :40]) and np.isnan(part[:, 40:]).all()


def test_who_is_behind_is_the_same_asked_for_any_subset_or_another_start() -> None:
    """The verdicts kept for a reference and a start are each obstacle's own: a subset, another order or
    another start gets what it would get afresh."""
    movers = [car("behind", 10.0, 16.0), car("leader", 60.0, 8.0), car("far", 0.0, 5.0, y=3.0)]
    assert [ob.id for ob in followers(REF, movers, 30.0)] == ["behind", "far"]
    assert [ob.id for ob in followers(REF, movers[::-1], 30.0)] == ["far", "behind"]
    assert [ob.id for ob in followers(REF, movers[1:], 30.0)] == ["far"]
    assert [ob.id for ob in followers(REF, movers, 5.0)] == ["far"]  # the ego behind the first car
    assert [ob.id for ob in followers(REF, movers, 70.0)] == ["behind", "leader", "far"]
    assert [ob.id for ob in followers(REF, movers, 30.0)] == ["behind", "far"]


def test_each_mover_is_near_the_path_within_its_own_reach() -> None:
    """A bus among the movers does not make a car on another road near the path: each obstacle's reach is
    twice the footprint's and its own (a car's about 16 m, a 12 m bus's about 30 m), whichever others
    it is given with; the bounds are those of every box mapped."""
    car_far = car("car", 60.0, 8.0, y=20.0)  # 20 m beside the path: beyond a car's reach
    bus = DynamicObstacle("bus", 12.0, 2.5, np.column_stack((T, 60.0 + 8.0 * T, 20.0 + 0 * T, 0 * T)))
    leader = car("leader", 60.0, 8.0)
    path = _path()
    along = Along.of(REF, path, _problem(car_far, bus, leader), DEFAULT_CONFIG)
    near, _, close = along.near([car_far, bus, leader], KNOTS)
    assert near.tolist() == [1, 2]  # the bus (its own reach) and the leader, not the car
    assert not close[0].any() and close[1].all() and close[2].all()
    alone, _, close_alone = along.near([car_far, leader], KNOTS)
    assert alone.tolist() == [1] and np.array_equal(close_alone, close[[0, 2]])

    problem = _problem(car_far, bus, leader)
    fast = space_time_bounds(REF, path, problem, KNOTS, 30.0)
    mapped_near = Along.near

    def everywhere(self: Along, movers: list[DynamicObstacle], t: np.ndarray) -> Any:
        _, states, close = mapped_near(self, movers, t)
        return np.arange(len(movers)), states, np.ones_like(close)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(Along, "near", everywhere)
        full = space_time_bounds(REF, path, problem, KNOTS, 30.0)
    assert fast.upper is not None and full.upper is not None
    assert np.array_equal(fast.upper, full.upper)


def _crossing_car(
    name: str, x: float, y0: float, speed: float, heading: float = 0.5 * np.pi
) -> DynamicObstacle:
    """A 4.5 m × 1.8 m car crossing the road at ``x`` [m] from ``y0`` [m] at ``speed`` [m/s] (along y)."""
    return DynamicObstacle(name, 4.5, 1.8, np.column_stack((T, x + 0 * T, y0 + speed * T, heading + 0 * T)))


def test_a_car_crossing_the_path_later_is_a_crossing_with_the_room_to_pass_in_front_of_it() -> None:
    """Off the path at the start, on it later, across it: ``before`` is ahead of where its box meets the
    footprint over the next headway (plus stop_gap) while it is on the path, −inf before and after."""
    crossing = _crossing_car(
        "crossing", 100.0, -40.0, 10.0
    )  # on the lane (|y| ≲ 6.5) for about t ∈ [3.4, 4.6]
    problem = _problem(crossing)
    found = crossings(REF, _path(), problem, KNOTS, 30.0)
    assert [c.id for c in found] == ["crossing"]
    before, least = found[0].before, found[0].least
    busy = np.isfinite(before)
    assert not busy[0] and not busy[-1] and busy.any()
    c = DEFAULT_CONFIG
    # its far side (x + 0.9) passed by our rear (2.25 + margin behind the centre), plus stop_gap
    expected = 100.0 + 0.9 + 2.25 + c.obstacle_margin - 30.0 + c.stop_gap
    assert np.all(before[busy] >= expected - 1e-9)
    assert np.all(before[busy] <= expected + 0.5 + 1e-9)  # one knot
    # over the headway ahead: busy a headway before it first meets the footprint; the least bound later
    first_met = KNOTS[busy][0]
    assert np.all(np.isfinite(least) <= busy)
    assert KNOTS[np.isfinite(least)][0] == pytest.approx(
        first_met + c.speed.headway - c.speed.follower_headway
    )


def test_a_car_crossing_over_at_a_shallow_angle_is_a_crossing_one_merging_at_it_is_not() -> None:
    """At 35° to the path (below crossing_angle) a car that goes from one side of the path to the other
    is crossing traffic, whose passing in front the speed stage may weigh (seen on a recorded scene: a car
    cutting diagonally across the road 57 m ahead in 6.5 s was followed as if it merged, and the ego
    braked for it); one that comes in at the same angle and stays in the lane merges."""
    angle = np.radians(35.0)
    t = T
    x = 100.0 + 12.0 * np.cos(angle) * (t - 4.0)
    over = DynamicObstacle(
        "over", 4.5, 1.8, np.column_stack((t, x, 12.0 * np.sin(angle) * (t - 4.0), angle + 0 * t))
    )
    y_in = np.minimum(12.0 * np.sin(angle) * (t - 4.0), 0.0)  # up to the lane's centre, then along it
    heading_in = np.where(y_in < 0.0, angle, 0.0)
    merging = DynamicObstacle("merging", 4.5, 1.8, np.column_stack((t, x, y_in, heading_in)))
    assert np.cos(angle) > np.cos(DEFAULT_CONFIG.speed.crossing_angle)  # shallower than a crossing
    assert [c.id for c in crossings(REF, _path(), _problem(over), KNOTS, 30.0)] == ["over"]
    assert crossings(REF, _path(), _problem(merging), KNOTS, 30.0) == []


def test_leaders_in_the_lane_cars_merging_along_it_and_cars_behind_are_no_crossings() -> None:
    leader = car("leader", 60.0, 8.0)  # on the path from the start
    merging = car("merging", 70.0, 8.0, y=np.linspace(4.5, 0.0, T.size))  # into the lane, along it
    behind = _crossing_car("behind", 20.0, -40.0, 10.0)  # crosses behind the ego
    oncoming = DynamicObstacle(  # the other way in the next lane
        "oncoming", 4.5, 1.8, np.column_stack((T, 200.0 - 10.0 * T, 3.5 + 0 * T, np.pi + 0 * T))
    )
    problem = _problem(leader, merging, behind, oncoming)
    assert crossings(REF, _path(), problem, KNOTS, 30.0) == []
    # the same car coming across is one
    across = _crossing_car("across", 90.0, -40.0, 10.0)
    assert [c.id for c in crossings(REF, _path(), _problem(leader, across), KNOTS, 30.0)] == ["across"]
