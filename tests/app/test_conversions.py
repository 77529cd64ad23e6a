"""app.conversions: a problem survives the round trip through a request; the answer writers refuse what
would be a wrong answer."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pydantic_core
import pytest

from app.conversions import demo_request, from_problem, plan_data, to_problem
from app.models.plan import STAGES, PlanResponse
from planner.follower import FollowerReason, UnescapedFollower
from planner.goal import Goal, GoalCircle, GoalPolygon
from planner.pipeline import plan
from planner.problem import Road
from planner.result import PlanResult
from planner.roads import demo_problem

DEMO_POINTS = demo_problem().reference_line.shape[0]


@pytest.fixture(scope="module")
def demo_plan() -> PlanResult:
    return plan(to_problem(demo_request()))


@pytest.mark.parametrize(
    "extra",
    [
        {},
        {
            "road": Road(left_width=np.full(DEMO_POINTS, 19.0), right_width=12.0),
            "goal": Goal(GoalPolygon(np.array([[0.0, 0.0], [4, 0], [0, 3]])), (1.0, 2.0), (0.0, 1.0)),
        },
        {"goal": Goal(GoalCircle(np.array([1.0, 2.0]), 3.0))},
        {"goal": Goal(time=(-1.0, 5.0))},
    ],
    ids=["demo", "road-and-polygon-goal", "circle-goal", "time-goal"],
)
def test_problem_round_trip(extra: dict[str, Any]) -> None:
    problem = dataclasses.replace(demo_problem(), **extra)
    problem = dataclasses.replace(problem, options=dataclasses.replace(problem.options, speed_limit=12.5))
    again = to_problem(from_problem(problem))
    assert np.array_equal(again.reference_line, problem.reference_line)
    assert again.lane == problem.lane
    assert again.ego == problem.ego
    assert again.vehicle == problem.vehicle
    assert again.options == problem.options
    assert len(again.obstacles) == len(problem.obstacles)
    for a, b in zip(again.obstacles, problem.obstacles, strict=True):
        assert type(a) is type(b) and a.id == b.id
    assert (again.road is None) == (problem.road is None)
    if problem.road is not None and again.road is not None:
        for side in ("left_width", "right_width"):
            np.testing.assert_array_equal(getattr(again.road, side), getattr(problem.road, side))
    assert (again.goal is None) == (problem.goal is None)
    if problem.goal is not None and again.goal is not None:
        assert (again.goal.time, again.goal.speed) == (problem.goal.time, problem.goal.speed)
        assert type(again.goal.position) is type(problem.goal.position)
        for name in ("polygon", "center", "radius"):
            if hasattr(problem.goal.position, name):
                np.testing.assert_array_equal(
                    getattr(again.goal.position, name), getattr(problem.goal.position, name)
                )


#: a request's budget and what it spent [ms]
SPENT = {"budget_ms": 1000.0, "waited_ms": 2.5, "ran_ms": 30.0}


def test_plan_data_is_the_response_model_json(demo_plan: PlanResult) -> None:
    data = plan_data(demo_plan, SPENT)
    model = PlanResponse.model_validate_json(pydantic_core.to_json(data), strict=True)
    assert model.model_dump(mode="json", exclude_none=True) == data
    assert list(data["diagnostics"]["timing_ms"]) == list(STAGES)
    assert data["diagnostics"]["request"] == SPENT
    assert len(data["trajectory"]) == demo_plan.trajectory.t.size
    assert data["trajectory"][-1]["v"] == pytest.approx(float(demo_plan.trajectory.v[-1]))


def test_plan_data_refuses_what_would_be_a_wrong_answer(demo_plan: PlanResult) -> None:
    v = demo_plan.trajectory.v.copy()
    v[2] = np.inf
    broken = dataclasses.replace(demo_plan, trajectory=dataclasses.replace(demo_plan.trajectory, v=v))
    with pytest.raises(ValueError, match="the trajectory holds a non-finite number"):
        plan_data(broken, SPENT)
    with pytest.raises(ValueError, match="unknown plan status 'maybe'"):
        plan_data(dataclasses.replace(demo_plan, status="maybe"), SPENT)  # type: ignore[arg-type]
    timing = {**demo_plan.diagnostics.timing_ms, "speed": float("nan")}
    diagnostics = dataclasses.replace(demo_plan.diagnostics, timing_ms=timing)
    with pytest.raises(ValueError, match="the diagnostics hold"):
        plan_data(dataclasses.replace(demo_plan, diagnostics=diagnostics), SPENT)


def test_plan_data_names_a_follower_only_when_there_is_one(demo_plan: PlanResult) -> None:
    assert "follower" not in plan_data(demo_plan, SPENT)["diagnostics"]
    follower = UnescapedFollower("car 7", 2.5, FollowerReason.SPEED_LIMIT)
    named = dataclasses.replace(
        demo_plan, diagnostics=dataclasses.replace(demo_plan.diagnostics, follower=follower)
    )
    data = plan_data(named, SPENT)
    assert data["diagnostics"]["follower"] == {"obstacle_id": "car 7", "t": 2.5, "reason": "speed_limit"}
    model = PlanResponse.model_validate_json(pydantic_core.to_json(data), strict=True)
    assert model.model_dump(mode="json", exclude_none=True) == data
