"""planner.goal and the problem's road: what they accept, and every refusal naming its field."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from planner.errors import InvalidInputError
from planner.goal import Goal, GoalCircle, GoalPolygon
from planner.problem import Lane, Options, Road
from planner.roads import demo_problem

TRIANGLE = np.array([[0.0, 0.0], [4.0, 0.0], [0.0, 3.0]])


def test_a_goal_keeps_what_it_is_given() -> None:
    goal = Goal(GoalPolygon(TRIANGLE.tolist()), time=[-1, 6], speed=(0, 2.5))  # type: ignore[arg-type]
    assert isinstance(goal.position, GoalPolygon)
    np.testing.assert_array_equal(goal.position.polygon, TRIANGLE)
    assert goal.time == (-1.0, 6.0) and goal.speed == (0.0, 2.5)
    assert Goal() == Goal(None, None, None)  # every part optional


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda: GoalPolygon(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]])), "goal.position.polygon"),
        (lambda: GoalPolygon(np.array([[0.0, 0.0], [1.0, 1.0]])), "goal.position.polygon"),
        (lambda: GoalPolygon(np.array([[0.0, 0.0], [1.0, np.nan], [0.0, 1.0]])), "goal.position.polygon"),
        (lambda: GoalCircle(np.array([0.0, 0.0]), 0.0), "goal.position.circle.radius"),
        (lambda: GoalCircle(np.array([0.0, np.inf]), 1.0), "goal.position.circle.center"),
        (lambda: Goal(time=(3.0, 1.0)), "goal.time"),
        (lambda: Goal(time=(0.0, np.nan)), "goal.time.1"),
        (lambda: Goal(time=(1.0,)), "goal.time"),  # type: ignore[arg-type]
        (lambda: Goal(speed=(-0.5, 1.0)), "goal.speed.0"),
        (lambda: Goal(position="here"), "goal.position"),  # type: ignore[arg-type]
    ],
)
def test_a_bad_goal_is_refused_naming_its_field(make: Any, field: str) -> None:
    with pytest.raises(InvalidInputError) as err:
        make()
    assert err.value.field == field


def test_a_road_holds_the_lane_at_every_point() -> None:
    problem = demo_problem()  # lane: 11 m left, 3.5 m right
    n = problem.reference_line.shape[0]
    wide = replace(problem, road=Road(left_width=np.full(n, 11.0), right_width=7.0))
    assert isinstance(wide.road, Road) and isinstance(wide.road, Lane)
    left = np.full(n, 12.0)
    left[5] = 10.0
    with pytest.raises(InvalidInputError) as err:
        replace(problem, road=Road(left_width=left, right_width=7.0))
    assert err.value.field == "road.left_width.5"
    with pytest.raises(InvalidInputError) as err:
        replace(problem, road=Road(left_width=12.0, right_width=3.0))
    assert err.value.field == "road.right_width"
    with pytest.raises(InvalidInputError) as err:
        replace(problem, road=Road(left_width=np.full(n - 1, 12.0), right_width=7.0))
    assert err.value.field == "road.left_width"
    with pytest.raises(InvalidInputError) as err:
        Road(left_width=-1.0, right_width=7.0)
    assert err.value.field == "road.left_width"


def test_the_speed_limit_is_at_least_the_target() -> None:
    assert Options(target_speed=5.0, speed_limit=5.0).speed_limit == 5.0
    assert Options(target_speed=None, speed_limit=3.0).speed_limit == 3.0
    with pytest.raises(InvalidInputError) as err:
        Options(target_speed=5.0, speed_limit=4.9)
    assert err.value.field == "options.speed_limit"
    with pytest.raises(InvalidInputError) as err:
        Options(speed_limit=float("nan"))
    assert err.value.field == "options.speed_limit"
