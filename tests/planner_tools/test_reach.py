"""The earliest arrival at a goal region within the limits (:mod:`planner_tools.reach`): the fastest profile
against closed forms, the bound of whole problems, and the two Flensburg goals it shows out of reach."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from planner.goal import Goal
from planner.problem import Ego, Lane, Options, PlanningProblem, Vehicle
from planner.roads import clothoid
from planner_tools.reach import arrival, fastest_speeds, reach
from tests.planner.goal_cases import CAR, EGO_X, box, straight_problem

LANE = (-1.75, 1.75)
SCENES = Path(__file__).resolve().parents[1] / "data" / "commonroad"


def test_from_rest_on_a_free_road_the_speed_is_that_of_full_acceleration() -> None:
    s = np.linspace(0.0, 100.0, 20001)
    v = fastest_speeds(s, np.full(s.shape, 1e3), 0.0, 2.0, 8.0)
    np.testing.assert_allclose(v, np.sqrt(2.0 * 2.0 * s), rtol=1e-12, atol=1e-12)
    assert arrival(s, v, 100.0) == pytest.approx(10.0, abs=1e-2)  # s = a t² / 2
    assert arrival(s, v, 100.5) == math.inf  # beyond the road


def test_a_dip_is_braked_for_fully_and_left_at_full_acceleration() -> None:
    s = np.linspace(0.0, 200.0, 4001)
    limit = np.where((s >= 50.0) & (s <= 60.0), 5.0, 30.0)
    v = fastest_speeds(s, limit, 20.0, 2.0, 8.0)
    assert v[0] == 20.0 and np.all(v[1:] <= limit[1:] + 1e-9)
    before = s < 50.0
    brake = np.sqrt(25.0 + 2.0 * 8.0 * (50.0 - s[before]))
    start = np.sqrt(20.0**2 + 2.0 * 2.0 * s[before])
    np.testing.assert_allclose(v[before], np.minimum(np.minimum(brake, start), 30.0), rtol=1e-9)
    after = s > 60.0
    np.testing.assert_allclose(v[after], np.minimum(np.sqrt(25.0 + 2.0 * 2.0 * (s[after] - 60.0)), 30.0))


def test_a_region_at_the_target_speed_beyond_the_window_is_late() -> None:
    # 95 m ahead at 10 m/s, the speed limit the target: 9.5 s, after the window's end at 8 s
    bound = reach(straight_problem(Goal(box(EGO_X + 95.0, EGO_X + 115.0, *LANE), time=(6.0, 8.0))))
    assert bound is not None
    assert bound.ahead == pytest.approx(95.0, abs=1e-6)
    assert bound.earliest == pytest.approx(9.5, abs=1e-3) and bound.earliest > bound.t_max
    assert bound.lateral_only == bound.earliest  # the point model has no steering rate
    # a speed limit of 16 m/s: full acceleration (2.5 m/s²) from 10 to 16 m/s over 31.2 m, then 16 m/s
    faster = reach(
        straight_problem(Goal(box(EGO_X + 95.0, EGO_X + 115.0, *LANE), time=(6.0, 8.0)), speed_limit=16.0)
    )
    assert faster is not None
    ramp = (16.0**2 - 10.0**2) / (2.0 * 2.5)
    assert faster.earliest == pytest.approx(6.0 / 2.5 + (95.0 - ramp) / 16.0, abs=1e-3)
    assert reach(straight_problem(Goal(box(EGO_X + 95.0, EGO_X + 115.0, *LANE)))) is None  # no window


def test_a_car_entering_a_bend_is_held_back_by_its_steering_rate() -> None:
    # a clothoid: the curvature grows at 0.02 1/m², so a car turns its wheel at ≈ v·W·0.02 rad/s
    road = clothoid(80.0, 0.02, step=0.5)
    end = road[-1]
    goal = Goal(box(end[0] - 6.0, end[0] + 6.0, end[1] - 6.0, end[1] + 6.0), time=(0.0, 10.0))
    car = Vehicle(**CAR, max_lateral_acceleration=8.0)  # type: ignore[arg-type]
    problem = PlanningProblem(
        road, Lane(3.5, 3.5), Ego(0.0, 0.0, 0.0, 15.0), (), car, Options(target_speed=15.0), goal=goal
    )
    bound = reach(problem)
    assert bound is not None
    assert math.isfinite(bound.earliest) and bound.earliest > bound.lateral_only
    point = reach(replace(problem, vehicle=Vehicle(max_lateral_acceleration=8.0)))
    assert point is not None and point.earliest == point.lateral_only


@pytest.mark.parametrize("scene", ["DEU_Flensburg-15_1_T-1", "DEU_Flensburg-58_1_T-1"])
def test_the_flensburg_goals_are_out_of_reach_along_the_lane(scene: str) -> None:
    # the goals of issue 13 these scenes miss: even with no jerk limit and no margin, the bends' steering
    # rate (0.4 rad/s) and lateral acceleration (4 m/s²) bring the centre to the region after 10 s
    pytest.importorskip("commonroad")
    from planner_tools.evaluate import Settings, prepare

    bound = reach(prepare(SCENES / f"{scene}.json", Settings(vehicle="car")).problem)
    assert bound is not None and bound.t_max == pytest.approx(10.0)
    assert bound.earliest > bound.t_max + 0.5
