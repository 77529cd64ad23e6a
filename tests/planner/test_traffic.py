"""The moving obstacles of the lane decision: nominal times, slow vehicles, traffic in the borrowed road."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.config import DEFAULT_CONFIG
from planner.ego import start_state
from planner.problem import DynamicObstacle, Lane, Options
from planner.reference import build_reference
from planner.roads import driving, straight, two_lane_problem
from planner.traffic import ego_times, leaders, slow_vehicle

ROAD = straight(300.0)
REF = build_reference(ROAD)


@settings(max_examples=40, deadline=None)
@given(speed=st.floats(0.0, 30.0), target=st.floats(1.0, 30.0))
def test_the_earliest_time_is_never_later_than_the_late_one_and_both_grow_along_the_road(
    speed: float, target: float
) -> None:
    problem = two_lane_problem(ROAD, speed=speed)
    problem = replace(problem, options=Options(target_speed=target))
    start = start_state(REF, problem)
    s = np.linspace(start.s, start.s + 200.0, 101)
    early, late = ego_times(REF, problem, start, s, DEFAULT_CONFIG)
    assert early[0] == pytest.approx(0.0, abs=1e-12) and late[0] == 0.0
    assert np.all(np.diff(early) > 0.0) and np.all(np.diff(late) > 0.0)
    assert np.all(early <= late + 1e-9)
    # at full acceleration up to the faster of the two speeds: never quicker than that speed allows
    assert np.all(early >= (s - start.s) / max(speed, target) - 1e-9)


def test_the_earliest_time_is_exact_on_a_straight_road() -> None:
    problem = two_lane_problem(ROAD, speed=0.0)
    problem = replace(problem, options=Options(target_speed=10.0))
    start = start_state(REF, problem)
    a = problem.vehicle.max_acceleration
    early, _ = ego_times(REF, problem, start, np.array([8.0, 100.0]), DEFAULT_CONFIG)
    # 8 m from a standstill at a: √(2·8/a); 100 m: 10/a s to reach 10 m/s over 50/a m, then at 10 m/s
    assert early[0] == np.sqrt(2.0 * 8.0 / a)
    np.testing.assert_allclose(early[1], 10.0 / a + (100.0 - 50.0 / a) / 10.0)


def test_a_slow_vehicle_in_the_lane_sweeps_a_box_until_the_vehicle_is_past_it() -> None:
    tractor = driving("tractor", 40.0, 0.0, 3.0, length=6.0, width=2.5)
    problem = two_lane_problem(ROAD, speed=12.0, obstacles=(tractor,))
    start = start_state(REF, problem)
    at = np.linspace(start.s, start.s + 150.0, 241)
    slow = slow_vehicle(REF, problem, start, at, DEFAULT_CONFIG)
    assert slow is not None and slow.obstacle_id == "tractor" and slow.swept is not None
    assert slow.s == pytest.approx(37.0, abs=1e-6)  # its rear now
    assert slow.swept.s_min[0] <= 37.0 + 1e-6 and slow.swept.s_max[0] > 43.0  # from now until passed
    # a vehicle as fast as the target, or one beside the lane, is no slow vehicle
    for other in (driving("car", 40.0, 0.0, 12.0), driving("car", 40.0, 3.5, 3.0)):
        assert (
            slow_vehicle(
                REF, two_lane_problem(ROAD, speed=12.0, obstacles=(other,)), start, at, DEFAULT_CONFIG
            )
            is None
        )


def test_a_long_slow_vehicle_beside_the_ego_is_not_yet_passed() -> None:
    # the ego in the opposite lane beside a 12 m truck whose centre is 4 m behind it and whose front is
    # 2 m ahead: the truck still blocks the lane the ego returns to (its centre alone is behind the ego)
    truck = driving("truck", 46.0, 0.0, 3.0, length=12.0, width=3.0)
    problem = two_lane_problem(ROAD, speed=10.0, obstacles=(truck,))
    problem = replace(problem, ego=replace(problem.ego, x=50.0, y=3.5))
    start = start_state(REF, problem)
    at = np.linspace(start.s, start.s + 100.0, 161)
    slow = slow_vehicle(REF, problem, start, at, DEFAULT_CONFIG)
    assert slow is not None and slow.obstacle_id == "truck" and slow.swept is not None
    assert slow.swept.s_max[0] > 52.0 + 3.0  # its front, and a headway ahead of it


def test_a_vehicle_whose_prediction_ends_within_the_horizon_is_as_fast_as_it_drives() -> None:
    # predicted over 2 s of an 8 s horizon: held where it ends, it would average 3 m/s over the horizon
    car = driving("car", 40.0, 0.0, 12.0, length=4.5, width=2.5)
    short = replace(car, prediction=car.prediction[car.prediction[:, 0] <= 2.0])
    problem = two_lane_problem(ROAD, speed=12.0, obstacles=(short,))
    start = start_state(REF, problem)
    at = np.linspace(start.s, start.s + 150.0, 241)
    assert slow_vehicle(REF, problem, start, at, DEFAULT_CONFIG) is None
    crawling = replace(car, prediction=driving("car", 40.0, 0.0, 1.0).prediction[:5])  # 1 m/s for 2 s
    slow = slow_vehicle(REF, replace(problem, obstacles=(crawling,)), start, at, DEFAULT_CONFIG)
    assert slow is not None and slow.obstacle_id == "car"


def test_within_the_lane_only_a_vehicle_leaving_room_and_going_the_same_way_is_a_slow_vehicle() -> None:
    start_problem = two_lane_problem(ROAD, speed=12.0)
    start = start_state(REF, start_problem)
    at = np.linspace(start.s, start.s + 150.0, 241)
    wide = Lane(4.5, 4.5)
    band = (-1.5, 1.5)  # the path's offsets and the vehicle's half width
    for speed, found in ((3.0, True), (0.1, True), (-3.0, False)):
        car = driving("car", 40.0, 0.0, speed)
        problem = replace(two_lane_problem(ROAD, speed=12.0, obstacles=(car,), road=False), lane=wide)
        slow = slow_vehicle(REF, problem, start, at, DEFAULT_CONFIG, in_lane=band)
        assert (slow is not None) is found
        # a lane it fills is the borrow's business, not a pass within it
        narrow = replace(problem, lane=Lane(1.75, 1.75))
        assert slow_vehicle(REF, narrow, start, at, DEFAULT_CONFIG, in_lane=band) is None
    # one off the path's band is not in the way
    aside_car = driving("car", 40.0, 3.0, 3.0)
    aside = replace(two_lane_problem(ROAD, speed=12.0, obstacles=(aside_car,), road=False), lane=wide)
    assert slow_vehicle(REF, aside, start, at, DEFAULT_CONFIG, in_lane=band) is None


def test_within_the_lane_a_vehicle_fast_over_the_ground_but_slow_along_the_reference_is_none() -> None:
    # it crosses the wide lane at 8 m/s: along the reference it does not move, over the ground it is fast
    start = start_state(REF, two_lane_problem(ROAD, speed=12.0))
    at = np.linspace(start.s, start.s + 150.0, 241)
    t = np.linspace(0.0, 60.0, 121)
    states = np.column_stack((t, np.full_like(t, 40.0), 8.0 * t, np.full_like(t, np.pi / 2)))
    crossing = DynamicObstacle("crossing", 4.5, 1.8, states)
    problem = replace(
        two_lane_problem(ROAD, speed=12.0, obstacles=(crossing,), road=False), lane=Lane(4.5, 4.5)
    )
    assert slow_vehicle(REF, problem, start, at, DEFAULT_CONFIG, in_lane=(-1.5, 1.5)) is None


def test_the_leaders_are_the_vehicles_ahead_going_the_same_way() -> None:
    t = np.linspace(0.0, 60.0, 121)
    crossing = DynamicObstacle(
        "crossing",
        4.5,
        1.8,
        np.column_stack((t, np.full_like(t, 30.0), -20.0 + 5.0 * t, np.full_like(t, np.pi / 2))),
    )
    obstacles = (
        driving("ahead", 30.0, 0.0, 5.0),  # ahead, same way: a leader, fast or slow
        driving("slower", 60.0, 1.0, 1.0),
        driving("towards", 50.0, 3.5, -8.0),  # oncoming
        driving("behind", -15.0, 0.0, 15.0),  # behind, same way
        driving("beside", 0.0, 3.5, 10.0),  # beside the vehicle now: not ahead of its front
        crossing,
    )
    problem = two_lane_problem(ROAD, speed=10.0, obstacles=obstacles)
    start = start_state(REF, problem)
    assert leaders(REF, problem, start, DEFAULT_CONFIG) == frozenset({"ahead", "slower"})
